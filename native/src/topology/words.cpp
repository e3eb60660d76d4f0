#include "surfmap/topology/words.h"

#include <algorithm>
#include <cstdint>
#include <cstdlib>

#include "surfmap/error.h"

namespace surfmap {

Word reduce(const Word& w) {
  Word out;
  out.reserve(w.size());
  for (int x : w) {
    if (!out.empty() && out.back() == -x)
      out.pop_back();
    else
      out.push_back(x);
  }
  return out;
}

Word inverse(const Word& w) {
  Word out(w.rbegin(), w.rend());
  for (int& x : out) x = -x;
  return out;
}

Word concat(const Word& u, const Word& v) {
  Word w = u;
  w.insert(w.end(), v.begin(), v.end());
  return reduce(w);
}

Word concat(std::initializer_list<Word> parts) {
  Word w;
  for (const Word& p : parts) w.insert(w.end(), p.begin(), p.end());
  return reduce(w);
}

Word cyclic_reduce(const Word& w) {
  Word r = reduce(w);
  size_t i = 0, j = r.size();
  while (j - i >= 2 && r[i] == -r[j - 1]) {
    ++i;
    --j;
  }
  return Word(r.begin() + i, r.begin() + j);
}

bool conjugate(const Word& u, const Word& v) {
  const Word a = cyclic_reduce(u), b = cyclic_reduce(v);
  if (a.size() != b.size()) return false;
  if (a.empty()) return true;
  Word doubled = a;
  doubled.insert(doubled.end(), a.begin(), a.end());
  return std::search(doubled.begin(), doubled.end(), b.begin(), b.end()) != doubled.end();
}

Word commutator_product(const std::vector<Word>& generators) {
  Word w;
  for (size_t i = 0; i + 1 < generators.size(); i += 2) {
    const Word& a = generators[i];
    const Word& b = generators[i + 1];
    w = concat({w, a, b, inverse(a), inverse(b)});
  }
  return w;
}

std::vector<Word> reduced_words_up_to(int genus, int radius) {
  std::vector<Word> out{{}}, frontier{{}};
  for (int r = 0; r < radius; ++r) {
    std::vector<Word> next;
    for (const Word& w : frontier)
      for (int x = -2 * genus; x <= 2 * genus; ++x) {
        if (x == 0 || (!w.empty() && w.back() == -x)) continue;
        Word v = w;
        v.push_back(x);
        next.push_back(std::move(v));
      }
    out.insert(out.end(), next.begin(), next.end());
    frontier = std::move(next);
  }
  return out;
}

size_t WordHash::operator()(const Word& w) const {
  // 64-bit FNV-1a over the letters, then a final mix.
  uint64_t h = 1469598103934665603ull ^ w.size();
  for (int x : w) h = (h ^ static_cast<uint32_t>(x)) * 1099511628211ull;
  h ^= h >> 29;
  return static_cast<size_t>(h * 0xbf58476d1ce4e5b9ull);
}

Word dehn_reduce(const Word& w, const Word& relator) { return DehnReducer(relator)(w); }

DehnReducer::DehnReducer(const Word& relator) {
  const int n = static_cast<int>(relator.size());
  if (n == 0) return;
  for (const Word& r : {relator, inverse(relator)})
    for (int s = 0; s < n; ++s) {
      Word rot(r.begin() + s, r.end());
      rot.insert(rot.end(), r.begin(), r.begin() + s);
      rotations_.push_back(std::move(rot));
    }
  for (int x : relator) max_letter_ = std::max(max_letter_, std::abs(x));
  by_first_.resize(2 * static_cast<size_t>(max_letter_) + 1);
  for (size_t k = 0; k < rotations_.size(); ++k)
    by_first_[static_cast<size_t>(rotations_[k].front() + max_letter_)].push_back(static_cast<int>(k));
}

void DehnReducer::run(Word& out, const int* in, size_t n_in, bool in_reduced) const {
  // Dehn's algorithm on a stack, left to right: after every letter pushed,
  // if the top m = floor(n/2)+1 letters are the first m letters of a
  // rotation r of R^±1, they are replaced by the shorter (r[m..n))^-1, fed
  // back through the input so that free cancellation and further
  // replacements cascade. A longer match would contain one of length m
  // ending at an earlier letter, found when that letter was pushed; letters
  // below the top never change except by popping back to a state already
  // checked. So the result is freely reduced and holds no more than half of
  // any rotation, in time linear in the input (every replacement shortens
  // the word), where rescanning from the start after each replacement was
  // quadratic (minutes on the 5e5-letter words of twisted classes). Only
  // the rotations starting with the window's first letter can match
  // (by_first_; the first match in the order of rotations_ is taken).
  const size_t n = rotations_.front().size(), m = n / 2 + 1;
  // Fed-back letters, next one at the back; they come before in[pos..).
  std::vector<int> pending;
  size_t pos = 0;
  // How many letters on top of `out` are in[pos - clean .. pos), pushed
  // unchanged (counted only when `in_reduced`). With m - 1 of them, no
  // further letter of a reduced input can cancel or complete a window (it
  // would lie inside the input), so the rest is copied as it is.
  size_t clean = 0;
  const size_t copy_after = std::max<size_t>(m - 1, 1);
  for (;;) {
    int x;
    bool from_input = false;
    if (!pending.empty()) {
      x = pending.back();
      pending.pop_back();
    } else if (pos < n_in) {
      if (in_reduced && clean >= copy_after) {
        out.insert(out.end(), in + pos, in + n_in);
        return;
      }
      x = in[pos++];
      from_input = true;
    } else {
      return;
    }
    if (!out.empty() && out.back() == -x) {
      out.pop_back();
      clean = 0;
      continue;
    }
    out.push_back(x);
    clean = from_input ? clean + 1 : 0;
    if (out.size() < m) continue;
    const int* top = out.data() + out.size() - m;
    const int first = top[0];
    if (std::abs(first) > max_letter_) continue;
    for (int k : by_first_[static_cast<size_t>(first + max_letter_)]) {
      const Word& r = rotations_[static_cast<size_t>(k)];
      size_t q = 1;
      while (q < m && r[q] == top[q]) ++q;
      if (q < m) continue;
      out.resize(out.size() - m);
      // (r[m..n))^-1, first letter last on the pending stack.
      for (size_t i = m; i < n; ++i) pending.push_back(-r[i]);
      clean = 0;
      break;
    }
  }
}

Word DehnReducer::operator()(const Word& w) const {
  if (rotations_.empty()) return reduce(w);
  Word out;
  out.reserve(w.size());
  run(out, w.data(), w.size(), false);
  return out;
}

std::vector<Word> DehnReducer::each(std::vector<Word> words) const {
  for (Word& w : words) w = (*this)(w);
  return words;
}

bool DehnReducer::holds_more_than_half(const Word& u, size_t start) const {
  const size_t m = window(), n = u.size();
  if (m == 0 || n < m) throw InputError("DehnReducer::holds_more_than_half: a window of " + std::to_string(m) +
                                        " letters in a word of " + std::to_string(n));
  const int first = u[start % n];
  if (std::abs(first) > max_letter_) return false;
  for (int k : by_first_[static_cast<size_t>(first + max_letter_)]) {
    const Word& r = rotations_[static_cast<size_t>(k)];
    size_t q = 1;
    while (q < m && r[q] == u[(start + q) % n]) ++q;
    if (q == m) return true;
  }
  return false;
}

Word DehnReducer::reduce_rotation(const Word& u, size_t r) const {
  if (r > u.size()) throw InputError("DehnReducer::reduce_rotation: rotation " + std::to_string(r) + " past the word's end (" +
                                          std::to_string(u.size()) + " letters)");
  if (rotations_.empty()) return reduce(concat(Word(u.begin() + static_cast<long>(r), u.end()),
                                               Word(u.begin(), u.begin() + static_cast<long>(r))));
  // u[r..) is a subword of a reduced word: pushed onto the stack it changes
  // nothing (no cancellation, no window of m letters of a rotation).
  Word out(u.begin() + static_cast<long>(r), u.end());
  out.reserve(u.size());
  run(out, u.data(), r, true);
  return out;
}

std::string to_text(const Word& w, const std::vector<std::string>& names) {
  std::string s;
  for (size_t i = 0; i < w.size(); ++i) {
    const int k = std::abs(w[i]);
    if (i) s += ' ';
    s += (k - 1 < static_cast<int>(names.size())) ? names[k - 1] : ("x" + std::to_string(k));
    if (w[i] < 0) s += "^-1";
  }
  return s;
}

}  // namespace surfmap
