#pragma once
// One spelling per enum value of SurfaceMapOptions (surface_map.h): the
// tables below are read by the CLI's option checks, the Python keyword
// arguments and the report (map/map_report.h), so the three always agree.
#include <array>
#include <string>
#include <utility>
#include <vector>

#include "surfmap/error.h"
#include "surfmap/map/surface_map.h"

namespace surfmap {

template <class E, size_t N>
using EnumNames = std::array<std::pair<E, const char*>, N>;

inline constexpr EnumNames<MapMethod, 2> kMapMethodNames{{
    {MapMethod::Newton, "newton"},
    {MapMethod::Relaxation, "relaxation"},
}};
inline constexpr EnumNames<InitialMapMethod, 3> kInitialMapMethodNames{{
    {InitialMapMethod::CutGraph, "cut_graph"},
    {InitialMapMethod::Polygon, "polygon"},
    {InitialMapMethod::UniformHarmonic, "uniform"},
}};
inline constexpr EnumNames<SourceWeights, 3> kSourceWeightsNames{{
    {SourceWeights::Automatic, "auto"},
    {SourceWeights::IntrinsicDelaunay, "intrinsic"},
    {SourceWeights::OwnEdges, "own"},
}};
inline constexpr EnumNames<UniformizationMetric, 4> kUniformizationMetricNames{{
    {UniformizationMetric::Automatic, "auto"},
    {UniformizationMetric::IntrinsicDelaunay, "flips"},
    {UniformizationMetric::FixedConnectivity, "fixed"},
    {UniformizationMetric::FixedFirst, "fixed-first"},
}};
inline constexpr EnumNames<LoopMetric, 3> kLoopMetricNames{{
    {LoopMetric::Automatic, "auto"},
    {LoopMetric::Embedding, "embedding"},
    {LoopMetric::Metric, "metric"},
}};
inline constexpr EnumNames<FaceCharts, 3> kFaceChartsNames{{
    {FaceCharts::Automatic, "auto"},
    {FaceCharts::Always, "always"},
    {FaceCharts::Never, "never"},
}};

/// The table of an enum, so the functions below need only the value type.
inline constexpr const auto& enum_names(MapMethod) { return kMapMethodNames; }
inline constexpr const auto& enum_names(InitialMapMethod) { return kInitialMapMethodNames; }
inline constexpr const auto& enum_names(SourceWeights) { return kSourceWeightsNames; }
inline constexpr const auto& enum_names(UniformizationMetric) { return kUniformizationMetricNames; }
inline constexpr const auto& enum_names(LoopMetric) { return kLoopMetricNames; }
inline constexpr const auto& enum_names(FaceCharts) { return kFaceChartsNames; }

/// The name of `value` in its table.
template <class E>
std::string enum_name(E value) {
  for (const auto& [v, name] : enum_names(E{}))
    if (v == value) return name;
  return "?";  // unreachable: every enumerator has a row
}

/// Every name of E's table, in order (for CLI11's IsMember check).
template <class E>
std::vector<std::string> enum_name_list() {
  std::vector<std::string> out;
  for (const auto& row : enum_names(E{})) out.emplace_back(row.second);
  return out;
}

/// The value named `name`; InputError "WHAT must be 'a', 'b' or 'c', not 'x'"
/// otherwise (`what`: the option's name, e.g. "initial_map").
template <class E>
E parse_enum(const std::string& name, const std::string& what) {
  std::string allowed;
  const auto& table = enum_names(E{});
  for (size_t i = 0; i < table.size(); ++i) {
    if (table[i].second == name) return table[i].first;
    allowed += (i == 0 ? "'" : i + 1 == table.size() ? " or '" : ", '") + std::string(table[i].second) + "'";
  }
  throw InputError(what + " must be " + allowed + ", not '" + name + "'");
}

}  // namespace surfmap
