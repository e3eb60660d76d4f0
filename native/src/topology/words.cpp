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
}

Word DehnReducer::operator()(const Word& w) const {
  const std::vector<Word>& rotations = rotations_;
  Word cur = reduce(w);
  for (bool changed = true; changed;) {
    changed = false;
    for (size_t i = 0; i < cur.size() && !changed; ++i)
      for (const Word& r : rotations) {
        size_t k = 0;
        while (k < r.size() && i + k < cur.size() && cur[i + k] == r[k]) ++k;
        if (2 * k <= r.size()) continue;
        // cur = X r[0..k) Y with r[0..k) r[k..n) = 1: r[0..k) = (r[k..n))^-1.
        Word next(cur.begin(), cur.begin() + i);
        const Word rest = inverse(Word(r.begin() + k, r.end()));
        next.insert(next.end(), rest.begin(), rest.end());
        next.insert(next.end(), cur.begin() + i + k, cur.end());
        cur = reduce(next);
        changed = true;
        break;
      }
  }
  return cur;
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
