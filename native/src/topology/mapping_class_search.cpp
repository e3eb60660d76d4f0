#include "surfmap/topology/mapping_class_search.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "surfmap/error.h"

namespace surfmap {
namespace {

int A(int i) { return 2 * i + 1; }
int B(int i) { return 2 * i + 2; }

// outer ∘ inner with Dehn-reduced words.
SurfaceAutomorphism then(const SurfaceAutomorphism& outer, const SurfaceAutomorphism& inner, const DehnReducer& reduce) {
  SurfaceAutomorphism r{compose(outer.map, inner.map), compose(inner.inverse, outer.inverse), outer.moves + inner.moves};
  r.map = reduce.each(std::move(r.map));
  r.inverse = reduce.each(std::move(r.inverse));
  return r;
}

SurfaceAutomorphism inverse_of(const SurfaceAutomorphism& a) { return {a.inverse, a.map, a.moves}; }

// L x L^-1.
SurfaceAutomorphism conjugated(const SurfaceAutomorphism& L, const SurfaceAutomorphism& x, const DehnReducer& reduce) {
  return then(then(L, x, reduce), inverse_of(L), reduce);
}

std::string inv_name(const std::string& s) { return s + "^-1"; }

size_t letters(const GroupMap& m) {
  size_t t = 0;
  for (const Word& w : m) t += w.size();
  return t;
}

}  // namespace

std::vector<MappingClassMove> twist_moves(int genus, bool torelli_conjugates, bool bounding_pairs) {
  if (genus < 2) throw InputError("twist_moves: genus " + std::to_string(genus) + " (needs genus >= 2)");
  const int n = 2 * genus;
  const DehnReducer reduce(canonical_relator(genus));
  auto hname = [](const char* c, int i) { return std::string("T(") + c + std::to_string(i + 1) + ")"; };
  // Twists along a_i (b_i -> b_i a_i) and b_i (a_i -> a_i b_i^-1), both of
  // the same handedness: on homology x -> x + <c, x> c for the curve's class
  // c, <a_i, b_i> = 1 (symplectic_form).
  std::vector<SurfaceAutomorphism> Ta(genus), Tb(genus), Tc(genus - 1), Ts(genus - 1);
  for (int i = 0; i < genus; ++i) {
    Ta[i] = {identity_map(n), identity_map(n), 1};
    Ta[i].map[B(i) - 1] = {B(i), A(i)};
    Ta[i].inverse[B(i) - 1] = {B(i), -A(i)};
    Tb[i] = {identity_map(n), identity_map(n), 1};
    Tb[i].map[A(i) - 1] = {A(i), -B(i)};
    Tb[i].inverse[A(i) - 1] = {A(i), B(i)};
  }
  for (int i = 0; i + 1 < genus; ++i) Tc[i] = conjugated(adjacent_handle_mixing(genus, i), Ta[i], reduce);
  for (int j = 1; j < genus; ++j) {
    Word C;
    for (int i = 0; i < j; ++i) C = concat({C, {A(i), B(i), -A(i), -B(i)}});
    SurfaceAutomorphism t{identity_map(n), identity_map(n), 1};
    for (int i = 0; i < j; ++i)
      for (int x : {A(i), B(i)}) {
        t.map[x - 1] = concat({C, {x}, inverse(C)});
        t.inverse[x - 1] = concat({inverse(C), {x}, C});
      }
    Ts[j - 1] = t;
  }
  std::vector<MappingClassMove> moves;
  auto add = [&](const std::string& name, const SurfaceAutomorphism& a) {
    if (!is_surface_automorphism(a, genus)) throw SolveError("twist_moves: " + name + " is not an automorphism");
    // (Some conjugates coincide as words: X disjoint from T(c_j)(s_j).)
    for (const MappingClassMove& m : moves)
      if (m.automorphism.map == a.map) return;
    moves.push_back({name, a});
    moves.push_back({inv_name(name), inverse_of(a)});
  };
  for (int i = 0; i < genus; ++i) add(hname("a", i), Ta[i]), add(hname("b", i), Tb[i]);
  for (int i = 0; i + 1 < genus; ++i) add(hname("c", i), Tc[i]);
  for (int j = 0; j + 1 < genus; ++j) add(hname("s", j), Ts[j]);
  if (torelli_conjugates) {
    // Of the Lickorish twists only T(c_j) crosses s_j (the others are
    // disjoint from it and commute with T(s_j)), so the conjugators are
    // T(c_j)^±1, T(c_j)^±2 and X T(c_j)^±1 for the twists X^±1 along
    // a_j, b_j, a_j+1, b_j+1: twists along the separating curves one or two
    // twists away from s_j.
    for (int j = 0; j + 1 < genus; ++j) {
      std::vector<std::pair<std::string, SurfaceAutomorphism>> conj;
      for (int e : {1, -1}) {
        const SurfaceAutomorphism C = e > 0 ? Tc[j] : inverse_of(Tc[j]);
        const std::string cn = e > 0 ? hname("c", j) : inv_name(hname("c", j));
        conj.push_back({cn, C});
        conj.push_back({cn + " " + cn, then(C, C, reduce)});
        const std::pair<std::string, const SurfaceAutomorphism*> xs[] = {
            {hname("a", j), &Ta[j]}, {hname("b", j), &Tb[j]}, {hname("a", j + 1), &Ta[j + 1]}, {hname("b", j + 1), &Tb[j + 1]}};
        for (const auto& [xn, X] : xs)
          for (int f : {1, -1})
            conj.push_back({(f > 0 ? xn : inv_name(xn)) + " " + cn, then(f > 0 ? *X : inverse_of(*X), C, reduce)});
      }
      for (const auto& [ln, L] : conj) add("[" + ln + "] " + hname("s", j), conjugated(L, Ts[j], reduce));
    }
  }
  if (bounding_pairs && genus >= 3) {
    // Genus-1 bounding pairs (Torelli elements the separating twists do not
    // generate; for genus >= 3 the bounding pair maps generate the Torelli
    // group, a known theorem). The 3-chain a_j, b_j, c_j has a neighbourhood of genus
    // 1 whose two boundary curves d, d' are disjoint and both homologous to
    // a_j+1, and the chain relation gives (T(a_j) T(b_j) T(c_j))^4 =
    // T(d) T(d'); so T(a_j+1)^2 (T(a_j) T(b_j) T(c_j))^-4 has the identity
    // homology (checked), and it is the bounding pair map T(a_j+1) T(d')^-1
    // when d is a_j+1 (not verified geometrically here; as a move it only
    // needs to be an exact Torelli element, which it is). Mirrored: the
    // chain c_j, b_j+1, a_j+1 and a_j. (In genus 2 both come out as the
    // identity and are not added.)
    const IntMatrix I = IntMatrix::Identity(n, n);
    auto chain_pair = [&](const SurfaceAutomorphism& x, const SurfaceAutomorphism& y, const SurfaceAutomorphism& z,
                          const SurfaceAutomorphism& t) {
      const SurfaceAutomorphism P = then(then(x, y, reduce), z, reduce);
      const SurfaceAutomorphism P2 = then(P, P, reduce), P4 = then(P2, P2, reduce);
      return then(then(t, t, reduce), inverse_of(P4), reduce);
    };
    for (int j = 0; j + 1 < genus; ++j) {
      const std::pair<std::string, SurfaceAutomorphism> bps[] = {
          {"BP(" + hname("a", j + 1) + "; " + hname("a", j) + " " + hname("b", j) + " " + hname("c", j) + ")",
           chain_pair(Ta[j], Tb[j], Tc[j], Ta[j + 1])},
          {"BP(" + hname("a", j) + "; " + hname("c", j) + " " + hname("b", j + 1) + " " + hname("a", j + 1) + ")",
           chain_pair(Tc[j], Tb[j + 1], Ta[j + 1], Ta[j])}};
      for (const auto& [name, a] : bps) {
        if (a.map == identity_map(n) || homology_matrix(a.map, n) != I)
          throw SolveError("twist_moves: " + name + " is not a nontrivial Torelli element");  // (never seen)
        add(name, a);
      }
    }
  }
  return moves;
}

TwistSearchResult twist_search(const GroupMap& start, double start_energy, int genus,
                               const std::function<double(const GroupMap&)>& screen,
                               const std::function<double(const GroupMap&)>& energy, const TwistSearchOptions& options) {
  auto at_least = [](const char* name, long long value, long long least) {
    if (value < least)
      throw InputError(std::string("twist_search: ") + name + " must be at least " + std::to_string(least) + ", got " +
                       std::to_string(value));
  };
  at_least("max_steps", options.max_steps, 0);
  at_least("max_evaluations", options.max_evaluations, 0);
  at_least("evaluations_per_step", options.evaluations_per_step, 1);
  at_least("screen_steps", options.screen_steps, 0);
  at_least("pair_starts", options.pair_starts, 0);
  at_least("kicks", options.kicks, 0);
  at_least("kick_moves", options.kick_moves, 1);
  at_least("kick_evaluations", options.kick_evaluations, 1);
  at_least("kick_choices", options.kick_choices, 1);
  if (!(options.tolerance >= 0) || !std::isfinite(options.tolerance))
    throw InputError("twist_search: tolerance must be finite and at least 0, got " + std::to_string(options.tolerance));
  const std::vector<MappingClassMove> moves = twist_moves(genus);
  const DehnReducer reduce(canonical_relator(genus));
  const Word R = canonical_relator(genus);
  const IntMatrix J = symplectic_form(genus);
  const int n = 2 * genus;
  TwistSearchResult res;
  res.best = start;
  res.start_energy = res.energy = start_energy;
  // Every screening is counted (TwistSearchResult::screened), the kicks' searches' too.
  auto screened = [&](const GroupMap& theta) {
    ++res.screened;
    return screen(theta);
  };
  std::vector<double> seen{screened(start)};
  auto is_seen = [&](double s) {
    for (double t : seen)
      if (std::abs(s - t) <= 1e-9 * std::max({1.0, std::abs(s), std::abs(t)})) return true;
    return false;
  };
  int evaluations = 0;
  struct Neighbour {
    GroupMap theta;
    std::string move;
    double screen;
  };
  auto neighbours = [&](const GroupMap& cur, bool only_new) {
    std::vector<Neighbour> nb;
    auto try_move = [&](const MappingClassMove& m, int side) {
      GroupMap theta = side == 0 ? compose(cur, m.automorphism.map) : compose(m.automorphism.map, cur);
      theta = reduce.each(std::move(theta));
      if (letters(theta) > options.max_letters) return;
      const double s = screened(theta);
      if (!std::isfinite(s) || (only_new && is_seen(s))) return;
      nb.push_back({std::move(theta), (side == 0 ? "source " : "target ") + m.name, s});
    };
    const bool side_on[2] = {options.source_side, options.target_side};
    for (const MappingClassMove& m : moves)
      for (int side = 0; side < 2; ++side)
        if (side_on[side]) try_move(m, side);
    // The one-sided moves (TwistSearchOptions::source_moves, target_moves).
    for (int side = 0; side < 2; ++side)
      if (side_on[side])
        for (const MappingClassMove& m : side == 0 ? options.source_moves : options.target_moves) try_move(m, side);
    return nb;
  };
  // Descent on the screening score (cheap), then one evaluation of its end.
  if (options.screen_steps > 0 && !options.kicks_only) {
    GroupMap cur = start;
    double cur_s = seen[0];
    for (int step = 0; step < options.screen_steps; ++step) {
      std::vector<Neighbour> nb = neighbours(cur, false);
      int best = -1;
      for (size_t k = 0; k < nb.size(); ++k)
        if (nb[k].screen < cur_s * (1 - 1e-9) && (best < 0 || nb[k].screen < nb[best].screen)) best = static_cast<int>(k);
      if (best < 0) break;
      cur = std::move(nb[best].theta);
      cur_s = nb[best].screen;
      res.screen_moves.push_back(nb[best].move);
      res.screen_scores.push_back(cur_s);
    }
    if (!res.screen_moves.empty() && evaluations < options.max_evaluations) {
      const double e = energy(cur);
      ++evaluations;
      res.evaluations.push_back({0, "screen descent (" + std::to_string(res.screen_moves.size()) + " moves)", cur_s,
                                 std::isfinite(e) ? e : std::numeric_limits<double>::infinity()});
      seen.push_back(cur_s);
      if (std::isfinite(e) && e < res.energy * (1 - options.tolerance)) {
        res.best = cur;
        res.energy = e;
        // (Only the end point was solved: the steps before it have NaN.)
        for (size_t k = 0; k < res.screen_moves.size(); ++k) {
          res.moves.push_back(res.screen_moves[k]);
          res.energies.push_back(k + 1 == res.screen_moves.size() ? e : std::numeric_limits<double>::quiet_NaN());
        }
      }
    }
  }
  res.stop_reason = options.kicks_only ? "kicks only" : "step budget";
  for (int step = 0; step < options.max_steps && !options.kicks_only; ++step) {
    std::vector<Neighbour> nb;
    for (Neighbour& x : neighbours(res.best, true))
      if (!is_seen(x.screen)) seen.push_back(x.screen), nb.push_back(std::move(x));
    std::stable_sort(nb.begin(), nb.end(), [](const Neighbour& x, const Neighbour& y) { return x.screen < y.screen; });
    int best = -1;
    double best_energy = res.energy * (1 - options.tolerance);
    const int k_max = std::min<int>(static_cast<int>(nb.size()), options.evaluations_per_step);
    const size_t first_evaluation = res.evaluations.size();
    for (int k = 0; k < k_max && evaluations < options.max_evaluations; ++k) {
      // The moves are exact automorphisms; this guards the composition.
      const IntMatrix M = homology_matrix(nb[k].theta, n);
      if (M.transpose() * J * M != J || !reduce(substitute(R, nb[k].theta)).empty())
        throw SolveError("twist_search: neighbour " + nb[k].move + " is not an isomorphism");
      const double e = energy(nb[k].theta);
      ++evaluations;
      res.evaluations.push_back({step, nb[k].move, nb[k].screen, std::isfinite(e) ? e : std::numeric_limits<double>::infinity()});
      if (std::isfinite(e) && e < best_energy) best_energy = e, best = k;
    }
    if (best < 0 && options.pair_moves && evaluations < options.max_evaluations) {
      // No single move improves: pairs, from the step's lowest neighbours.
      std::vector<int> firsts;
      for (size_t k = first_evaluation; k < res.evaluations.size(); ++k) firsts.push_back(static_cast<int>(k - first_evaluation));
      std::stable_sort(firsts.begin(), firsts.end(), [&](int x, int y) {
        return res.evaluations[first_evaluation + x].energy < res.evaluations[first_evaluation + y].energy;
      });
      std::vector<Neighbour> pairs;
      for (int f = 0; f < std::min<int>(options.pair_starts, static_cast<int>(firsts.size())); ++f)
        for (Neighbour& x : neighbours(nb[firsts[f]].theta, true))
          if (!is_seen(x.screen)) {
            seen.push_back(x.screen);
            x.move = nb[firsts[f]].move + ", " + x.move;
            pairs.push_back(std::move(x));
          }
      std::stable_sort(pairs.begin(), pairs.end(), [](const Neighbour& x, const Neighbour& y) { return x.screen < y.screen; });
      const int p_max = std::min<int>(static_cast<int>(pairs.size()), options.evaluations_per_step);
      for (int k = 0; k < p_max && evaluations < options.max_evaluations; ++k) {
        const IntMatrix M = homology_matrix(pairs[k].theta, n);
        if (M.transpose() * J * M != J || !reduce(substitute(R, pairs[k].theta)).empty())
          throw SolveError("twist_search: pair " + pairs[k].move + " is not an isomorphism");
        const double e = energy(pairs[k].theta);
        ++evaluations;
        res.evaluations.push_back({step, pairs[k].move, pairs[k].screen, std::isfinite(e) ? e : std::numeric_limits<double>::infinity()});
        if (std::isfinite(e) && e < best_energy) best_energy = e, best = k;
      }
      if (best >= 0) {
        nb = std::move(pairs);
        ++res.pair_steps;
      } else if (evaluations < options.max_evaluations) {
        res.stop_reason = "no improving neighbour or pair";
        break;
      }
    }
    if (best < 0) {
      res.stop_reason = evaluations >= options.max_evaluations ? "evaluation budget" : "no improving neighbour";
      break;
    }
    res.best = std::move(nb[best].theta);
    res.energy = best_energy;
    res.moves.push_back(nb[best].move);
    res.energies.push_back(best_energy);
    if (evaluations >= options.max_evaluations) {
      res.stop_reason = "evaluation budget";
      break;
    }
  }
  // Iterated local search (TwistSearchOptions::kicks): kick the best class
  // by random moves, descend from there, keep the end when it is lower.
  if (options.kicks > 0) {
    std::mt19937 rng(options.kick_seed);
    TwistSearchOptions inner = options;
    inner.kicks = 0;
    inner.screen_steps = 0;
    inner.kicks_only = false;
    for (int kick = 0; kick < options.kicks && evaluations < options.max_evaluations; ++kick) {
      // Each kick move: one of the current class's `kick_choices` neighbours
      // of lowest screen, drawn at random (uniform moves would mostly leave
      // the letter limit or the caller's bound).
      // (Neighbours are screened by `neighbours`, counted in `screened`; the
      // kick's end is its last move's neighbour, whose screen is finite.)
      GroupMap cur = res.best;
      double s = 0;
      std::string path;
      bool made = true;
      for (int j = 0; j < options.kick_moves && made; ++j) {
        std::vector<Neighbour> nb = neighbours(cur, false);
        std::stable_sort(nb.begin(), nb.end(), [](const Neighbour& x, const Neighbour& y) { return x.screen < y.screen; });
        nb.resize(std::min<size_t>(nb.size(), static_cast<size_t>(options.kick_choices)));
        if (nb.empty()) {
          made = false;
          break;
        }
        std::uniform_int_distribution<size_t> pick(0, nb.size() - 1);
        Neighbour& x = nb[pick(rng)];
        cur = std::move(x.theta);
        s = x.screen;
        path += (path.empty() ? "" : ", ") + x.move;
      }
      if (!made) continue;  // (no neighbour to move to: not a kick)
      ++res.kicks;
      const std::string name = "kick " + std::to_string(kick + 1) + " (" + path + ")";
      const double e = energy(cur);
      ++evaluations;
      res.evaluations.push_back({-1, name, s, std::isfinite(e) ? e : std::numeric_limits<double>::infinity()});
      // (An infinite start, e.g. a kick the caller's bound prunes, is
      // descended from too: any finite neighbour is lower.)
      inner.max_evaluations = std::min(options.kick_evaluations, options.max_evaluations - evaluations);
      TwistSearchResult r = inner.max_evaluations > 0 ? twist_search(cur, e, genus, screen, energy, inner) : TwistSearchResult{};
      if (inner.max_evaluations <= 0) r.best = cur, r.energy = std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
      evaluations += static_cast<int>(r.evaluations.size());
      res.screened += r.screened;
      for (TwistSearchEvaluation& ev : r.evaluations) {
        ev.move = name + ": " + ev.move;
        ev.step = -1;
        res.evaluations.push_back(std::move(ev));
      }
      if (r.energy < res.energy * (1 - options.tolerance)) {
        ++res.improving_kicks;
        res.best = std::move(r.best);
        res.energy = r.energy;
        res.moves.push_back(name);
        res.energies.push_back(e);
        for (size_t k = 0; k < r.moves.size(); ++k) res.moves.push_back(r.moves[k]), res.energies.push_back(r.energies[k]);
      }
    }
    res.stop_reason += "; " + std::to_string(res.kicks) + " kicks, " + std::to_string(res.improving_kicks) + " lower";
  }
  return res;
}

}  // namespace surfmap
