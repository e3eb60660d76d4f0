// Exact algebra of outer automorphisms of surface groups
// (topology/outer_automorphisms.h; docs/handle_classes.md "Both directions").
#include "surfmap/topology/outer_automorphisms.h"

#include <algorithm>
#include <cstdlib>
#include <limits>

#include "surfmap/error.h"
#include "surfmap/topology/mapping_class_search.h"

namespace surfmap {

namespace {

Word rotated(const Word& u, size_t r) {
  Word v(u.begin() + static_cast<long>(r), u.end());
  v.insert(v.end(), u.begin(), u.begin() + static_cast<long>(r));
  return v;
}

// The rotations worth trying on a Dehn-reduced word of length n whose
// relator has at most m letters: every one for short words; for long ones a
// half turn brings every junction-spanning piece (at most m letters) inside.
std::vector<size_t> rotations(size_t n, size_t m) {
  std::vector<size_t> r;
  if (n < 2) return r;
  if (n <= 2 * m + 2) {
    for (size_t k = 1; k < n; ++k) r.push_back(k);
  } else {
    r.push_back(n / 2);
  }
  return r;
}

size_t total_letters(const GroupMap& m) {
  size_t s = 0;
  for (const Word& w : m) s += w.size();
  return s;
}

void check_map(const GroupMap& phi, int genus, const char* who) {
  if (genus < 2) throw InputError(std::string(who) + ": genus must be at least 2");
  if (static_cast<int>(phi.size()) != 2 * genus)
    throw InputError(std::string(who) + ": " + std::to_string(phi.size()) + " generator images, expected " +
                     std::to_string(2 * genus));
  for (const Word& w : phi)
    for (int x : w)
      if (x == 0 || std::abs(x) > 2 * genus)
        throw InputError(std::string(who) + ": letter " + std::to_string(x) + " out of range");
}

// Probe curves for the descent: x_i, then x_i x_j and x_i x_j^-1 (i < j).
std::vector<Word> probe_words(int genus) {
  const int n = 2 * genus;
  std::vector<Word> p;
  for (int i = 1; i <= n; ++i) p.push_back({i});
  for (int i = 1; i <= n; ++i)
    for (int j = i + 1; j <= n; ++j) {
      p.push_back({i, j});
      p.push_back({i, -j});
    }
  return p;
}

// probe_curve_cost (header) with the probe words and the memo prepared
// once per descent.
size_t probe_cost(const GroupMap& tau, const std::vector<Word>& probes, CyclicLengthMemo& memo,
                  size_t limit = std::numeric_limits<size_t>::max()) {
  size_t c = 0;
  for (const Word& p : probes) {
    c += memo(substitute(p, tau));
    if (c >= limit) return c;
  }
  return c;
}

}  // namespace

Word cyclic_dehn_reduce(const Word& w, const DehnReducer& reduce) {
  // u is Dehn-reduced and cyclically freely reduced, so reducing a rotation
  // u[r..) u[..r) changes it only where a window of m letters spanning u's
  // ends (starting at s in [L - m + 1, L - 1], cyclically) holds more than
  // half a relator and lies inside that rotation (s + m - L <= r <= s);
  // every change shortens it. So the first rotation tried that shortens is
  // the first one holding such a window, found without reducing the others
  // (the same word as reducing every rotation in turn).
  const size_t m = reduce.window();
  Word u = cyclic_reduce(reduce(w));
  for (;;) {
    const size_t L = u.size();
    if (m == 0 || L < m) return u;
    std::vector<size_t> spanning;  // starts s of the windows across the ends that hold more than half
    for (size_t s = L - m + 1; s < L; ++s)
      if (reduce.holds_more_than_half(u, s)) spanning.push_back(s);
    if (spanning.empty()) return u;
    size_t chosen = 0;
    for (size_t r : rotations(L, 64) /* relators up to genus 16 */) {
      for (size_t s : spanning)
        if (s + m - L <= r && r <= s) chosen = r;
      if (chosen) break;
    }
    if (!chosen) return u;
    u = cyclic_reduce(reduce.reduce_rotation(u, chosen));
  }
}

CyclicLengthMemo::CyclicLengthMemo(const DehnReducer& reduce, size_t max_letters)
    : reduce_(reduce), max_letters_(max_letters) {}

size_t CyclicLengthMemo::operator()(const Word& w) {
  const auto it = lengths_.find(w);
  if (it != lengths_.end()) {
    ++hits_;
    return it->second;
  }
  ++misses_;
  const size_t length = cyclic_dehn_reduce(w, reduce_).size();
  if (letters_ + w.size() > max_letters_) {
    lengths_.clear();
    letters_ = 0;
  }
  if (w.size() <= max_letters_) {
    lengths_.emplace(w, length);
    letters_ += w.size();
  }
  return length;
}

size_t probe_curve_cost(const GroupMap& tau, int genus, CyclicLengthMemo* memo, size_t limit) {
  check_map(tau, genus, "probe_curve_cost");
  const DehnReducer reduce(canonical_relator(genus));
  size_t c = 0;
  for (const Word& p : probe_words(genus)) {
    const Word image = substitute(p, tau);
    c += memo ? (*memo)(image) : cyclic_dehn_reduce(image, reduce).size();
    if (c >= limit) return c;
  }
  return c;
}

InnerTest inner_automorphism_test(const GroupMap& phi, int genus) {
  check_map(phi, genus, "inner_automorphism_test");
  InnerTest t;
  const int n = 2 * genus;
  if (homology_matrix(phi, n) != IntMatrix::Identity(n, n)) {
    t.why = "it acts on homology as a non-identity matrix";
    return t;
  }
  const DehnReducer reduce(canonical_relator(genus));
  // Peel phi(a1) = w u w^-1 down to u = a1 (file comment).
  Word w, u = reduce(phi[0]);
  for (int guard = 0; guard < 100000 && !(u.size() == 1 && u[0] == 1); ++guard) {
    if (u.size() >= 2 && u.front() == -u.back()) {
      w.push_back(u.front());
      u = Word(u.begin() + 1, u.end() - 1);
      continue;
    }
    bool shorter = false;
    for (size_t r = 1; r < u.size() && !shorter; ++r) {
      Word d = reduce(rotated(u, r));
      if (d.size() < u.size()) {
        w = reduce(concat(w, Word(u.begin(), u.begin() + static_cast<long>(r))));
        u = std::move(d);
        shorter = true;
      }
    }
    if (!shorter) break;
  }
  if (!(u.size() == 1 && u[0] == 1)) {
    t.why = "the image of a1 is not conjugate to a1";
    return t;
  }
  w = reduce(w);
  // w is determined up to powers of a1 (its centralizer): fix them with b1.
  const Word v = reduce(concat({inverse(w), phi[1], w}));
  const long range = static_cast<long>(v.size()) + 1;
  bool found = false;
  for (long k = 0; k <= range && !found; ++k)
    for (long s : {k, -k}) {
      const Word ak(static_cast<size_t>(std::abs(s)), s >= 0 ? 1 : -1);
      if (reduce(concat({inverse(ak), v, ak})) == Word{2}) {
        w = reduce(concat(w, ak));
        found = true;
        break;
      }
    }
  if (!found) {
    t.why = "the images of a1 and b1 are not conjugate to a1, b1 by one element";
    return t;
  }
  for (int x = 1; x <= n; ++x)
    if (!reduce(concat({inverse(w), phi[x - 1], w, Word{-x}})).empty()) {
      t.why = "no single conjugation gives every generator's image (generator " + std::to_string(x) + ")";
      return t;
    }
  t.inner = true;
  t.conjugator = w;
  return t;
}

OppositeClasses compare_opposite_classes(const GroupMap& psi, const GroupMap& theta, int genus) {
  OppositeClasses r;
  const DehnReducer reduce(canonical_relator(genus));
  r.composite = compose(psi, theta);
  for (Word& w : r.composite) w = reduce(w);
  r.inner = inner_automorphism_test(r.composite, genus);
  r.up_to_hyperelliptic =
      !r.inner.inner && genus == 2 && inner_automorphism_test(compose(r.composite, hyperelliptic_involution()), 2).inner;
  return r;
}

GroupMap hyperelliptic_involution() {
  const int g = 2;
  const DehnReducer reduce(canonical_relator(g));
  GroupMap h(4);
  for (int i = 0; i < g; ++i) {
    const int a = 2 * i + 1, b = 2 * i + 2;
    h[a - 1] = reduce({a, b, -a, -b, -a});  // (ab) a^-1 (ab)^-1
    h[b - 1] = reduce({a, -b, -a});         // (ab) b^-1 (ab)^-1
  }
  const std::vector<MappingClassMove> moves = twist_moves(g, false, false);
  const auto s1 = std::find_if(moves.begin(), moves.end(), [](const MappingClassMove& m) { return m.name == "T(s1)"; });
  if (s1 == moves.end()) throw SolveError("hyperelliptic_involution: no twist T(s1)");
  for (int k = 0; k <= 2; ++k)
    for (int sign : {1, -1}) {
      GroupMap c = h;
      for (int q = 0; q < k; ++q) c = reduce.each(compose(c, sign > 0 ? s1->automorphism.map : s1->automorphism.inverse));
      if (inner_automorphism_test(reduce.each(compose(c, c)), g).inner) return c;
    }
  throw SolveError("hyperelliptic_involution: no involution among the half turns and separating twists (a bug)");
}

namespace {

}  // namespace

GroupMap nielsen_inverse(const GroupMap& phi, int genus, size_t max_letters) {
  const int n = 2 * genus;
  if (static_cast<int>(phi.size()) != n) return {};
  const DehnReducer reduce(canonical_relator(genus));
  // t_i = phi(u_i) throughout: t starts as the images of the generators,
  // u as the generators; a Nielsen move t_i <- t_i t_j^e (or t_j^e t_i), or
  // the conjugation of every other t_i by t_j^e, is matched on u. Greedy:
  // the move that shortens the total Dehn-reduced length of t most; each
  // step shortens it, so at most that many steps.
  std::vector<Word> t(n), u(n);
  size_t total = 0;
  for (int i = 0; i < n; ++i) {
    t[i] = reduce(phi[i]);
    u[i] = {i + 1};
    total += t[i].size();
  }
  for (;;) {
    size_t best = total;
    int bi = -1, bj = -1, be = 0, kind = 0;  // kind 0: right factor, 1: left factor, 2: conjugation of all
    Word bt;
    for (int j = 0; j < n; ++j)
      for (int e : {1, -1}) {
        const Word tj = e > 0 ? t[j] : inverse(t[j]), tj_inv = inverse(tj);
        size_t conjugated = total;
        for (int i = 0; i < n; ++i) {
          if (i == j) continue;
          for (int k : {0, 1}) {
            Word c = k == 0 ? concat(t[i], tj) : concat(tj, t[i]);
            const size_t candidate = total - t[i].size() + c.size();
            if (candidate < best) best = candidate, bi = i, bj = j, be = e, kind = k, bt = std::move(c);
          }
          conjugated += concat({tj, t[i], tj_inv}).size();
          conjugated -= t[i].size();
        }
        if (conjugated < best) best = conjugated, bi = -1, bj = j, be = e, kind = 2;
      }
    if (best >= total) break;
    const Word uj = be > 0 ? u[bj] : inverse(u[bj]);
    if (kind == 2) {
      const Word tj = be > 0 ? t[bj] : inverse(t[bj]), tj_inv = inverse(tj), uj_inv = inverse(uj);
      for (int i = 0; i < n; ++i) {
        if (i == bj) continue;
        t[i] = concat({tj, t[i], tj_inv});
        u[i] = concat({uj, u[i], uj_inv});
        if (u[i].size() > max_letters) return {};
      }
    } else {
      u[bi] = kind == 0 ? concat(u[bi], uj) : concat(uj, u[bi]);
      if (u[bi].size() > max_letters) return {};
      t[bi] = std::move(bt);
    }
    total = best;
  }
  // Every t_i conjugate to a single letter y^±1 (by a common conjugator when
  // the inverse exists): u_i^±1 is a preimage of y up to that conjugation,
  // so the map y -> u_i^±1 is phi^-1 up to an inner automorphism; the caller
  // checks that exactly.
  GroupMap preimages(n);
  std::vector<bool> seen(n, false);
  for (int i = 0; i < n; ++i) {
    const Word c = cyclic_dehn_reduce(t[i], reduce);
    if (c.size() != 1) return {};
    const int y = c[0], k = std::abs(y) - 1;
    if (seen[k]) return {};
    seen[k] = true;
    preimages[k] = y > 0 ? u[i] : inverse(u[i]);
  }
  return preimages;
}

namespace {

/// Whether psi is phi's inverse up to an inner automorphism, exactly: phi ∘
/// psi and psi ∘ phi inner (both: the check of every inverse returned).
bool inverse_up_to_inner(const GroupMap& phi, const GroupMap& psi, int genus, const DehnReducer& reduce) {
  return inner_automorphism_test(reduce.each(compose(phi, psi)), genus).inner &&
         inner_automorphism_test(reduce.each(compose(psi, phi)), genus).inner;
}

}  // namespace

AutomorphismInverse invert_product(const std::vector<GroupMap>& factors, int genus,
                                   const std::vector<GroupMap>& known_inverses,
                                   const AutomorphismInverseOptions& options) {
  AutomorphismInverse out;
  if (factors.empty()) {
    out.why = "no factors";
    return out;
  }
  const DehnReducer reduce(canonical_relator(genus));
  GroupMap product = identity_map(2 * genus), inverse = identity_map(2 * genus);
  for (size_t i = 0; i < factors.size(); ++i) {
    check_map(factors[i], genus, "invert_product");
    GroupMap inverse_i;
    if (i < known_inverses.size() && !known_inverses[i].empty()) {
      check_map(known_inverses[i], genus, "invert_product");
      inverse_i = known_inverses[i];
    } else {
      AutomorphismInverse f = invert_automorphism(factors[i], genus, options);
      if (!f.ok) {
        out.why = "factor " + std::to_string(i + 1) + " of " + std::to_string(factors.size()) + " not inverted: " + f.why;
        return out;
      }
      out.moves += f.moves;
      inverse_i = std::move(f.inverse);
    }
    // (The letters of outer ∘ inner, before reduction: the product of the
    // factors' lengths at worst, so capped.)
    auto letters = [](const GroupMap& outer, const GroupMap& inner) {
      size_t total = 0;
      for (const Word& w : inner)
        for (int x : w) total += outer[static_cast<size_t>(std::abs(x) - 1)].size();
      return total;
    };
    const size_t most = options.max_product_letters;
    if (letters(product, factors[i]) > most || letters(inverse_i, inverse) > most) {
      out.why = "the product or its inverse up to factor " + std::to_string(i + 1) + " exceeds " +
                std::to_string(most) + " letters";
      return out;
    }
    product = reduce.each(compose(product, factors[i]));
    inverse = reduce.each(compose(inverse_i, inverse));
  }
  if (!inverse_up_to_inner(product, inverse, genus, reduce)) {
    out.why = "the factors' inverses composed are not the product's inverse (a known inverse is wrong)";
    return out;
  }
  out.ok = true;
  out.inverse = std::move(inverse);
  return out;
}

AutomorphismInverse invert_automorphism(const GroupMap& phi, int genus, const AutomorphismInverseOptions& options) {
  check_map(phi, genus, "invert_automorphism");
  AutomorphismInverse out;
  const int n = 2 * genus;
  const IntMatrix P = homology_matrix(phi, n), J = symplectic_form(genus);
  if (P.transpose() * J * P != J) {
    out.why = "its homology matrix is not symplectic";
    return out;
  }
  const DehnReducer reduce(canonical_relator(genus));
  // When the descent stalls: Nielsen reduction of phi's generator images
  // (nielsen_inverse), checked exactly like the descent's inverse.
  auto nielsen_fallback = [&](AutomorphismInverse& failed) {
    if (!options.nielsen) return failed;
    GroupMap inv = nielsen_inverse(phi, genus, options.max_letters);
    if (inv.empty()) {
      failed.why += "; Nielsen reduction of the generator images stalled";
      return failed;
    }
    inv = reduce.each(inv);
    if (!inverse_up_to_inner(phi, inv, genus, reduce)) {
      failed.why += "; Nielsen reduction's inverse is not one (a bug)";
      return failed;
    }
    failed.ok = true;
    failed.inverse = std::move(inv);
    failed.why = "inverted by Nielsen reduction after the descent: " + failed.why;
    return failed;
  };
  // States tau = L ∘ phi ∘ R; once tau is inner, phi^-1 = R ∘ L (up to
  // inner). A beam of the `beam` lowest-cost states, each step moving every
  // state by one move on either side (or, when none shortens, by a pair on
  // the right) to a strictly lower cost.
  struct State {
    GroupMap tau, left, right;
    size_t cost = 0;
  };
  const std::vector<MappingClassMove> moves = twist_moves(genus);
  const std::vector<Word> probes = probe_words(genus);
  CyclicLengthMemo memo(reduce);
  std::vector<State> beam{{reduce.each(phi), identity_map(n), identity_map(n), probe_cost(reduce.each(phi), probes, memo)}};
  // A second start: the exact lift sigma of the inverse homology on the
  // right (lift_symplectic), leaving a Torelli element to descend.
  if (P != IntMatrix::Identity(n, n)) try {
      const SurfaceAutomorphism sigma = lift_symplectic(-J * P.transpose() * J);  // P^-1
      GroupMap tau = reduce.each(compose(phi, sigma.map));
      const size_t c = probe_cost(tau, probes, memo);
      beam.push_back({std::move(tau), identity_map(n), reduce.each(sigma.map), c});
    } catch (const Error&) {
      // (entries too large to lift: the first start alone)
    }
  // A state is done when tau is inner, or when tau ∘ sigma is for the exact
  // lift sigma of tau's inverse homology: signed handle permutations (handle
  // swaps, half and quarter turns) keep every probe's cyclic length, so the
  // descent cannot see them, and their lifts are short.
  auto finished = [&](State& st) {
    if (inner_automorphism_test(st.tau, genus).inner) return true;
    const IntMatrix H = homology_matrix(st.tau, n);
    if (H == IntMatrix::Identity(n, n)) return false;
    try {
      const SurfaceAutomorphism sigma = lift_symplectic(-J * H.transpose() * J);
      GroupMap t = reduce.each(compose(st.tau, sigma.map));
      if (!inner_automorphism_test(t, genus).inner) return false;
      st.tau = std::move(t);
      st.right = reduce.each(compose(st.right, sigma.map));
      return true;
    } catch (const Error&) {
      return false;
    }
  };
  // A stalled state may be periodic (a rotation of a symmetric polygon
  // shortens under no move; the teapot -> double torus class has order 10
  // as an automorphism). The order of a periodic class of genus g is at
  // most 4g + 2 (Wiman), so tau^m inner for some m <= 4g + 2 gives
  // tau^-1 = tau^(m-1) exactly: then phi^-1 = R ∘ tau^(m-1) ∘ L.
  auto periodic = [&](State& st) {
    GroupMap power = st.tau;  // tau^m
    for (int m = 2; m <= 4 * genus + 2; ++m) {
      GroupMap previous = power;  // tau^(m-1)
      power = reduce.each(compose(power, st.tau));
      if (total_letters(power) > std::max(options.max_letters, 2 * total_letters(st.tau))) return false;
      if (!inner_automorphism_test(power, genus).inner) continue;
      st.right = reduce.each(compose(st.right, previous));
      st.tau = std::move(power);
      return true;
    }
    return false;
  };
  std::vector<State> starts = beam;  // (tried for periodicity too when the descent stalls)
  const State* done = nullptr;
  for (int step = 0;; ++step) {
    for (State& st : beam)
      if (finished(st)) {
        done = &st;
        break;
      }
    if (done) break;
    if (step >= options.max_steps) {
      out.why = "the descent used its " + std::to_string(options.max_steps) + " moves before reaching an inner automorphism";
      return nielsen_fallback(out);
    }
    std::vector<State> next;
    for (const State& st : beam) {
      const size_t letter_cap = std::max(options.max_letters, 2 * total_letters(st.tau));
      std::vector<std::pair<size_t, size_t>> singles;  // (cost, right move)
      auto consider = [&](const GroupMap& m, bool right, size_t* cost_out) {
        GroupMap cand = reduce.each(right ? compose(st.tau, m) : compose(m, st.tau));
        if (total_letters(cand) > letter_cap) return false;
        const size_t c = probe_cost(cand, probes, memo, cost_out ? std::numeric_limits<size_t>::max() : st.cost);
        if (cost_out) *cost_out = c;
        if (!(c < st.cost)) return false;
        next.push_back({std::move(cand), right ? st.left : reduce.each(compose(m, st.left)),
                        right ? reduce.each(compose(st.right, m)) : st.right, c});
        return true;
      };
      bool any = false;
      for (size_t k = 0; k < moves.size(); ++k) {
        size_t c = std::numeric_limits<size_t>::max();
        any = consider(moves[k].automorphism.map, true, &c) || any;
        singles.emplace_back(c, k);
        any = consider(moves[k].automorphism.map, false, nullptr) || any;
      }
      if (!any && options.pair_moves) {
        std::sort(singles.begin(), singles.end());
        for (size_t q = 0; q < singles.size() && q < static_cast<size_t>(options.pair_starts); ++q)
          for (const MappingClassMove& m2 : moves)
            consider(reduce.each(compose(moves[singles[q].second].automorphism.map, m2.automorphism.map)), true, nullptr);
      }
    }
    if (next.empty()) {
      for (std::vector<State>* states : {&beam, &starts}) {
        for (State& st : *states)
          if (periodic(st)) {
            done = &st;
            break;
          }
        if (done) break;
      }
      if (done) break;
      out.why = "no move or pair of moves shortens the probe curves' images (stopped after " + std::to_string(step) +
                " moves, not inner, not periodic)";
      return nielsen_fallback(out);
    }
    std::stable_sort(next.begin(), next.end(), [](const State& a, const State& b) { return a.cost < b.cost; });
    beam.clear();
    for (State& st : next) {
      if (static_cast<int>(beam.size()) >= std::max(1, options.beam)) break;
      bool seen = false;
      for (const State& b : beam) seen = seen || (b.cost == st.cost && b.tau == st.tau);
      if (!seen) beam.push_back(std::move(st));
    }
    ++out.moves;
  }
  GroupMap M = reduce.each(compose(done->right, done->left));
  GroupMap inv = std::move(M);
  if (!inverse_up_to_inner(phi, inv, genus, reduce)) {
    out.why = "the composite with the computed inverse is not inner (a bug)";
    return out;
  }
  out.ok = true;
  out.inverse = std::move(inv);
  return out;
}

}  // namespace surfmap
