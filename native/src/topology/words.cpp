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
