#include "surfmap/topology/words.h"

#include <algorithm>
#include <cstdlib>

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
  by_first_letter_.assign(2 * max_letter_ + 1, {});
  for (size_t q = 0; q < rotations_.size(); ++q)
    by_first_letter_[rotations_[q].front() + max_letter_].push_back(static_cast<int>(q));
}

Word DehnReducer::operator()(const Word& w) const {
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
  // quadratic (minutes on the 5e5-letter words of twisted classes).
  if (rotations_.empty()) return reduce(w);
  const size_t n = rotations_.front().size(), m = n / 2 + 1;
  Word out;
  out.reserve(w.size());
  Word input(w.rbegin(), w.rend());  // next letter at the back
  while (!input.empty()) {
    const int x = input.back();
    input.pop_back();
    if (!out.empty() && out.back() == -x) {
      out.pop_back();
      continue;
    }
    out.push_back(x);
    if (out.size() < m) continue;
    const int* top = out.data() + out.size() - m;
    if (std::abs(top[0]) > max_letter_) continue;
    for (int q : by_first_letter_[top[0] + max_letter_]) {
      const Word& r = rotations_[q];
      if (!std::equal(r.begin(), r.begin() + m, top)) continue;
      out.resize(out.size() - m);
      // (r[m..n))^-1, first letter last on the input stack.
      for (size_t q = m; q < n; ++q) input.push_back(-r[q]);
      break;
    }
  }
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
