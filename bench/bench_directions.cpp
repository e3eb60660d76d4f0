// Whether two separate runs of a pair, S -> T and T -> S, chose inverse
// handle classes (issue 14's "forward and reverse classes inverse"), from
// their `surfmap map --report` files alone: exactly the relation the
// two-way run computes (compare_opposite_classes of
// topology/outer_automorphisms.h, Dehn's algorithm), with each run's class
// written in the other's letters through the reports' identity overlays
// (quality.directions.source_as_target_inverse).
//
// Usage: bench_directions S_TO_T.json T_TO_S.json
// Prints one line: "inverse", "inverse up to the hyperelliptic involution",
// "not inverse: <why>" or "not compared: <why>" (a report without class words
// or letters); exit status 0 unless a file cannot be read.
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "surfmap/topology/handle_basis.h"
#include "surfmap/topology/outer_automorphisms.h"

using namespace surfmap;

namespace {

bool read_report(const char* path, nlohmann::json& report) {
  std::ifstream in(path);
  if (!in) {
    std::fprintf(stderr, "bench_directions: cannot open %s\n", path);
    return false;
  }
  try {
    in >> report;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_directions: %s is not a report: %s\n", path, e.what());
    return false;
  }
  return true;
}

GroupMap words(const nlohmann::json& report, const char* key) {
  GroupMap out;
  const auto& q = report.value("quality", nlohmann::json::object());
  const auto& d = q.value("directions", nlohmann::json::object());
  if (!d.contains(key) || !d[key].is_array()) return out;
  for (const auto& w : d[key]) out.push_back(w.get<Word>());
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: bench_directions S_TO_T.json T_TO_S.json\n");
    return 2;
  }
  nlohmann::json forward, reverse;
  if (!read_report(argv[1], forward) || !read_report(argv[2], reverse)) return 1;
  const int genus = forward.value("genus", 0);
  if (genus < 2 || reverse.value("genus", 0) != genus) {
    std::printf("not compared: genus %d and %d (classes of genus >= 2 only)\n", genus, reverse.value("genus", 0));
    return 0;
  }
  const GroupMap theta = words(forward, "chosen_class_words");
  const GroupMap psi = words(reverse, "chosen_class_words");
  const GroupMap s_as_target_inv = words(forward, "source_as_target_inverse");
  const GroupMap t_as_target_inv = words(reverse, "source_as_target_inverse");
  const size_t n = 2 * static_cast<size_t>(genus);
  if (theta.size() != n || psi.size() != n) {
    std::printf("not compared: a report has no class words\n");
    return 0;
  }
  if (s_as_target_inv.size() != n || t_as_target_inv.size() != n) {
    std::printf("not compared: a report has no letters as a target (source_as_target_inverse)\n");
    return 0;
  }
  // psi in the forward run's letters, as the two-way run writes it (two_way_run.cpp reverse_class_here).
  const GroupMap psi_here = compose(s_as_target_inv, compose(psi, t_as_target_inv));
  const OppositeClasses relation = compare_opposite_classes(psi_here, theta, genus);
  if (relation.inner.inner)
    std::printf("inverse (conjugator of %zu letters)\n", relation.inner.conjugator.size());
  else if (relation.up_to_hyperelliptic)
    std::printf("inverse up to the hyperelliptic involution\n");
  else
    std::printf("not inverse: %s\n", relation.inner.why.c_str());
  return 0;
}
