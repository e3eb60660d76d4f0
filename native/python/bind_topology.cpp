// Topology layer bindings: the system of loops (docs/method.md §2.2).
#include "bindings.h"
#include "convert.h"

#include "surfmap/mesh/intake.h"
#include "surfmap/topology/system_of_loops.h"

namespace py = pybind11;

namespace surfmap::python {

void bind_topology(py::module_& m) {
  m.def(
      "system_of_loops",
      [](py::handle V, py::handle F, int base_vertex, bool refine) {
        const RowMatrixX3d v = to_vertices(V);
        const RowMatrixX3i f = to_triangles(F);
        SystemOfLoops s;
        {
          py::gil_scoped_release release;
          const IntakeResult in = intake(v, f);  // validation; throws InputError
          SystemOfLoopsOptions opt;
          opt.base_vertex = base_vertex;
          opt.refine = refine;
          s = system_of_loops(in.mesh, opt);
        }
        py::dict d;
        d["V"] = to_numpy(s.mesh.V);
        d["F"] = to_numpy(s.mesh.F);
        d["origin_face"] = to_numpy(s.origin_face);
        d["origin_barycentric"] = to_numpy(s.origin_barycentric);
        d["genus"] = s.genus;
        d["base_vertex"] = s.base_vertex;
        py::list loops;
        for (const auto& L : s.loops) loops.append(to_numpy(L));
        d["loops"] = loops;
        d["generator_edges"] = to_numpy(s.generator_edges);
        d["tree_parent_halfedge"] = to_numpy(s.tree_parent_halfedge);
        d["dual_tree_parent_halfedge"] = to_numpy(s.dual_tree_parent_halfedge);
        d["word"] = s.word;
        d["word_text"] = s.word_text;
        return d;
      },
      py::arg("V"), py::arg("F"), py::arg("base_vertex") = -1, py::arg("refine") = true,
      R"doc(System of loops of a closed surface of genus g >= 1 (docs/method.md §2.2).

V: float64 (n, 3), F: int (m, 3). Returns a dict: refined mesh "V", "F" (its
first n vertices are the input's), "origin_face" / "origin_barycentric" (where
every refined vertex lies on the input), "genus", "base_vertex", "loops" (2g
int arrays [x, ..., x] of refined-vertex indices, simple and disjoint except
at x when refine=True), "generator_edges", "tree_parent_halfedge",
"dual_tree_parent_halfedge" (halfedge h = 3*f + k of F), "word" (cyclic
boundary word of the 4g-gon, letters +-(k+1) for loop k) and "word_text".
Raises InputError for an invalid mesh or genus 0.)doc");
}

}  // namespace surfmap::python
