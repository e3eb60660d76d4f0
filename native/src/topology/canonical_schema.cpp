#include "surfmap/topology/canonical_schema.h"

#include <algorithm>
#include <array>
#include <cstdlib>
#include <string>

#include "surfmap/error.h"

namespace surfmap {
namespace {

int position_of(const Word& w, int letter) {
  for (size_t i = 0; i < w.size(); ++i)
    if (w[i] == letter) return static_cast<int>(i);
  return -1;
}

void check_schema_word(const Word& word) {
  if (word.empty() || word.size() % 4 != 0)
    throw InputError("a boundary word of a closed orientable surface has length 4g; got " +
                     std::to_string(word.size()));
  const int n = static_cast<int>(word.size()) / 2;
  std::vector<int> plus(n + 1, 0), minus(n + 1, 0);
  for (int x : word) {
    if (x == 0 || std::abs(x) > n)
      throw InputError("letter " + std::to_string(x) + " is out of range for a word of length " +
                       std::to_string(word.size()));
    ++(x > 0 ? plus : minus)[std::abs(x)];
  }
  for (int k = 1; k <= n; ++k)
    if (plus[k] != 1 || minus[k] != 1)
      throw InputError("loop letter " + std::to_string(k) + " occurs " + std::to_string(plus[k]) +
                       " times forward and " + std::to_string(minus[k]) +
                       " times reversed; each must occur once each way");
}

}  // namespace

int schema_vertex_count(const Word& w) {
  // Side p (letter x > 0) runs corner p -> p+1; the side of x^-1 at q runs
  // corner q+1 -> q in x's direction, so gluing identifies p ~ q+1, p+1 ~ q.
  const int n = static_cast<int>(w.size());
  std::vector<int> parent(n);
  for (int i = 0; i < n; ++i) parent[i] = i;
  auto find = [&](int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (int p = 0; p < n; ++p) {
    if (w[p] < 0) continue;
    const int q = position_of(w, -w[p]);
    if (q < 0) continue;
    parent[find(p)] = find((q + 1) % n);
    parent[find((p + 1) % n)] = find(q);
  }
  int classes = 0;
  for (int i = 0; i < n; ++i) classes += find(i) == i;
  return classes;
}

CanonicalSchema canonical_schema(const Word& word, const CanonicalSchemaOptions& options) {
  check_schema_word(word);
  if (const int nv = schema_vertex_count(word); nv != 1)
    throw InputError("the boundary word glues the polygon's corners into " + std::to_string(nv) +
                     " vertices; a system of loops through one base vertex gives exactly 1");
  CanonicalSchema out;
  out.genus = static_cast<int>(word.size()) / 4;
  // Invariant: word ~ [done generators' commutators] * rest (cyclically,
  // i.e. up to conjugation), with `rest` a word in the original letters
  // that still uses each remaining letter once with each sign.
  Word rest = word;
  std::vector<std::array<int, 2>> consumed;  // the letters (a, b) of each move
  while (!rest.empty() && options.short_generators) {
    // The pair at rest[0] = a: W = a B b C a^-1 D b^-1 F (b^-1 after a^-1:
    // with nothing before a, every partner's other occurrence is there).
    // As below, W = Q [a', b'] F with Q = D C B; here G W = G [a'', b''] Q F
    // with the new pair conjugated instead, a'' = Q a' Q^-1 = a C^-1 D^-1
    // and b'' = Q b' Q^-1 = D C B b D^-1, and Q F = D C B F is the new rest.
    const int n = static_cast<int>(rest.size());
    const int j = position_of(rest, -rest[0]);
    Word best_a, best_b, best_rest;
    int best_b_letter = 0;
    for (int k = 1; k < j; ++k) {
      const int l = position_of(rest, -rest[k]);
      if (l < j) continue;  // not interleaved with a
      const Word B(rest.begin() + 1, rest.begin() + k), C(rest.begin() + k + 1, rest.begin() + j),
          D(rest.begin() + j + 1, rest.begin() + l), F(rest.begin() + l + 1, rest.end());
      Word a2 = concat({Word{rest[0]}, inverse(C), inverse(D)});
      Word b2 = concat({D, C, B, Word{rest[k]}, inverse(D)});
      if (best_b_letter != 0 && a2.size() + b2.size() >= best_a.size() + best_b.size()) continue;
      best_a = std::move(a2), best_b = std::move(b2), best_b_letter = rest[k];
      best_rest = D;
      best_rest.insert(best_rest.end(), C.begin(), C.end());
      best_rest.insert(best_rest.end(), B.begin(), B.end());
      best_rest.insert(best_rest.end(), F.begin(), F.end());
    }
    if (best_b_letter == 0 || static_cast<int>(best_rest.size()) != n - 4)
      throw InputError("the boundary word has a letter with no interleaved partner; it is not the "
                       "word of a one-vertex schema of an orientable surface");
    out.generators.push_back(std::move(best_a));
    out.generators.push_back(std::move(best_b));
    consumed.push_back({rest[0], best_b_letter});
    rest = std::move(best_rest);
    ++out.moves;
  }
  while (!rest.empty()) {
    const int n = static_cast<int>(rest.size());
    // Find x at i with x^-1 at j > i and a letter y occurring once in (i, j)
    // and once outside: an interleaved pair (x, y).
    int i = -1, j = -1, k = -1;
    for (int p = 0; p < n && k < 0; ++p) {
      const int q = position_of(rest, -rest[p]);
      if (q < p) continue;
      for (int r = p + 1; r < q; ++r) {
        const int s = position_of(rest, -rest[r]);
        if (s > q || s < p) {
          i = p, j = q, k = r;
          break;
        }
      }
    }
    if (k < 0)
      throw InputError("the boundary word has a letter with no interleaved partner; it is not the "
                       "word of a one-vertex schema of an orientable surface");
    // Rotate so the word starts at x: rest = P x ..., and move P to the end;
    // conjugating the finished commutators by P keeps the invariant.
    const Word P(rest.begin(), rest.begin() + i);
    Word rotated(rest.begin() + i, rest.end());
    rotated.insert(rotated.end(), P.begin(), P.end());
    for (Word& g : out.generators) g = concat({inverse(P), g, P});
    j -= i;
    k -= i;
    int b = rotated[k];
    int l = position_of(rotated, -b);  // l > j: y^-1 is after x^-1
    // W = a B b C a^-1 D b^-1 F
    const Word B(rotated.begin() + 1, rotated.begin() + k);
    const Word C(rotated.begin() + k + 1, rotated.begin() + j);
    const Word D(rotated.begin() + j + 1, rotated.begin() + l);
    const Word F(rotated.begin() + l + 1, rotated.end());
    const Word a{rotated[0]}, bw{b};
    // b' = b C B,  a' = B^-1 C^-1 D^-1 a B. Then rotated = Q [a',b'] F with
    // Q = D C B, so G rotated ~ (Q^-1 G Q) [a',b'] (F D C B): the finished
    // generators are conjugated by Q and F D C B is what is left.
    const Word Q = concat({D, C, B});
    for (Word& g : out.generators) g = concat({inverse(Q), g, Q});
    out.generators.push_back(concat({inverse(B), inverse(C), inverse(D), a, B}));
    out.generators.push_back(concat({bw, C, B}));
    Word next = F;
    next.insert(next.end(), D.begin(), D.end());
    next.insert(next.end(), C.begin(), C.end());
    next.insert(next.end(), B.begin(), B.end());
    rest = std::move(next);
    consumed.push_back({rotated[0], b});
    ++out.moves;
  }
  // Back-substitution. Generator 2m (2m+1) is U x V with x the letter a (b)
  // consumed by move m, and U, V words in letters consumed by later moves
  // only (B, C, D and the later conjugators P, Q come from the rest word,
  // which no longer holds a and b). So letters are solved last move first.
  const int n = static_cast<int>(word.size()) / 2;
  std::vector<Word> letter_in_gens(n + 1);
  std::vector<char> known(n + 1, 0);
  auto substitute = [&](const Word& w) {
    Word r;
    for (int x : w) {
      const int k = std::abs(x);
      if (!known[k]) throw SolveError("canonical_schema: back-substitution met an unsolved letter");
      const Word& e = letter_in_gens[k];
      r = concat(r, x > 0 ? e : inverse(e));
    }
    return r;
  };
  for (int m = out.moves - 1; m >= 0; --m) {
    for (int which = 0; which < 2; ++which) {
      const int x = consumed[m][which];
      const Word& g = out.generators[2 * m + which];
      const auto it = std::find_if(g.begin(), g.end(), [&](int y) { return std::abs(y) == std::abs(x); });
      if (it == g.end() || std::count_if(g.begin(), g.end(), [&](int y) { return std::abs(y) == std::abs(x); }) != 1)
        throw SolveError("canonical_schema: generator does not contain its letter exactly once");
      const Word U(g.begin(), it), V(it + 1, g.end());
      // g = U y V with y = ±|x|:  y = U^-1 g V^-1 (in generators).
      const Word gen{2 * m + which + 1};
      Word y = concat({inverse(substitute(U)), gen, inverse(substitute(V))});
      if (*it < 0) y = inverse(y);
      letter_in_gens[std::abs(x)] = y;
      known[std::abs(x)] = 1;
    }
  }
  out.letters.assign(letter_in_gens.begin() + 1, letter_in_gens.end());
  return out;
}

}  // namespace surfmap
