#include "fuzz_intake.h"

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <unistd.h>

#include "surfmap/error.h"
#include "surfmap/geometry/mollify.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/mesh/mesh_io.h"

namespace surfmap::fuzz {
namespace {

[[noreturn]] void fail(const std::string& what) {
  std::cerr << "fuzz_intake: " << what << std::endl;
  std::abort();
}

void check_message(const std::string& msg) {
  if (msg.empty()) fail("an InputError with an empty message");
  if (msg.find('\n') != std::string::npos) fail("a multi-line InputError message: " + msg);
  if (msg.size() > 2000) fail("an InputError message of " + std::to_string(msg.size()) + " characters");
}

// What a valid intake promises the solvers.
void check_valid_result(const IntakeResult& r) {
  const Connectivity conn(r.mesh.F, r.mesh.num_vertices());
  if (conn.euler_characteristic() != 2 - 2 * r.info.genus) fail("genus does not match the Euler characteristic");
  Eigen::VectorXd l(conn.num_edges());
  for (int e = 0; e < conn.num_edges(); ++e)
    l[e] = (r.mesh.V.row(conn.edge_vertex(e, 0)) - r.mesh.V.row(conn.edge_vertex(e, 1))).norm();
  const MollifyResult m = mollify_edge_lengths(l, conn);
  if (m.faces_touched != r.info.mollified_faces) fail("the mollification note disagrees with the solvers");
  for (int f = 0; f < conn.num_faces(); ++f) {
    const double a = m.lengths[conn.edge(3 * f)], b = m.lengths[conn.edge(3 * f + 1)],
                 c = m.lengths[conn.edge(3 * f + 2)];
    if (!(a > 0 && b > 0 && c > 0 && a < b + c && b < a + c && c < a + b))
      fail("face " + std::to_string(f) + " is not a strict triangle after mollification");
  }
}

}  // namespace

const char* extension_for(uint8_t selector) {
  static const char* const ext[4] = {".obj", ".off", ".ply", ".stl"};
  return ext[selector % 4];
}

std::string run_intake_input(const uint8_t* data, size_t size, const std::string& scratch_dir) {
  if (size == 0) return "ok";
  const std::string path = scratch_dir + "/surfmap_fuzz_" + std::to_string(::getpid()) + extension_for(data[0]);
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data + 1), static_cast<std::streamsize>(size - 1));
    if (!out) fail("cannot write the scratch file " + path);
  }
  std::string outcome = "ok";
  try {
    const PolygonSoup soup = read_polygon_soup(path);
    const MeshInfo info = inspect(soup);
    for (const auto& p : info.problems) check_message(p);
    for (const auto& n : info.notes) check_message(n);
    try {
      const IntakeResult r = intake(soup);
      if (!info.valid) fail("intake accepted a mesh that inspect called invalid");
      check_valid_result(r);
    } catch (const InputError& e) {
      if (info.valid) fail(std::string("intake refused a mesh that inspect called valid: ") + e.what());
      throw;
    }
  } catch (const InputError& e) {
    check_message(e.what());
    outcome = e.what();
  }
  std::remove(path.c_str());
  return outcome;
}

}  // namespace surfmap::fuzz
