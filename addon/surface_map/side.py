"""One object of a map (source or target) as plain data (no bpy): its mesh as the solve sees it,
its polygon layout for writing results back on the object's own corners, and where the results
go. Filled by the bpy side (ops_map.read_side), used by map_job, uv_transfer, morph."""
from dataclasses import dataclass, field
import hashlib
from typing import Any, Dict, List, Optional, Tuple

import numpy as np


class ObjectProblem(Exception):
    """A problem with one object's mesh or the selection; the message names the object."""


def fingerprint(V, F):
    """Hex digest of a triangulated mesh's vertex positions (float32) and triangles: changes
    when a vertex moves or the connectivity changes, not when the object is moved."""
    h = hashlib.sha1()
    V = np.ascontiguousarray(V, dtype=np.float32)
    F = np.ascontiguousarray(F, dtype=np.int32)
    h.update(np.int64([len(V), len(F)]).tobytes())
    h.update(V.tobytes())
    h.update(F.tobytes())
    return h.hexdigest()[:20]


def mesh_topology(num_vertices, num_faces, edge_vertices, loop_edges):
    """(genus, boundary loops) of a mesh from its connectivity alone, for the panel's summary
    before any solve: `edge_vertices` (E, 2) the edges' vertex pairs, `loop_edges` (L,) the
    edge of each face corner (Blender's `loops[].edge_index`). Boundary edges are those of one
    face; the boundary loops are the connected pieces of those edges; V - E + F = 2 - 2g - b for
    one connected surface. The genus is None when that gives no whole number >= 0 (several
    pieces, loose or non-manifold parts: Compute Map's intake then says what is wrong)."""
    edge_vertices = np.asarray(edge_vertices, dtype=np.int64).reshape(-1, 2)
    loop_edges = np.asarray(loop_edges, dtype=np.int64).ravel()
    uses = np.bincount(loop_edges, minlength=len(edge_vertices))
    parent = {}

    def root(v):
        while parent.setdefault(v, v) != v:
            parent[v] = parent[parent[v]]
            v = parent[v]
        return v
    for a, b in edge_vertices[uses == 1].tolist():
        ra, rb = root(a), root(b)
        if ra != rb:
            parent[ra] = rb
    loops = len({root(v) for v in list(parent)})
    twice_genus = 2 - (num_vertices - len(edge_vertices) + num_faces) - loops
    genus = twice_genus // 2 if twice_genus >= 0 and twice_genus % 2 == 0 else None
    return genus, loops


def describe_counts(genus, loops):
    """'closed, genus 2' / 'genus 0, 1 boundary loop' / 'not one surface' for the panel."""
    if genus is None:
        return "not one surface"
    if not loops:
        return f"closed, genus {genus}"
    return f"genus {genus}, {loops} boundary loop{'s' if loops != 1 else ''}"


@dataclass
class MeshSide:
    """The source or the target of a map.

    V (n,3) float64 local coordinates; F (m,3) int32 triangles (Blender's loop triangles,
    re-oriented outward when `flipped`); tri_loops (m,3) the mesh loop (face corner) of each
    triangle corner, ordered like F; tri_polygon (m,) the polygon of each triangle;
    loop_start / loop_total (P,) and loop_vertex (L,): Blender's polygon layout;
    uv_layers {name: (L,2)}; vertex_groups {name: (indices, weights)}."""
    name: str
    V: np.ndarray
    F: np.ndarray
    tri_loops: np.ndarray
    tri_polygon: np.ndarray
    num_polygons: int
    loop_start: np.ndarray
    loop_total: np.ndarray
    loop_vertex: np.ndarray
    matrix: np.ndarray                       # 4x4 world matrix
    evaluated: bool = False                  # read from the mesh with modifiers applied
    same_topology: bool = True               # ... which has the object's own vertices/corners
    uv_layers: Dict[str, np.ndarray] = field(default_factory=dict)
    vertex_groups: Dict[str, Tuple[List[int], List[float]]] = field(default_factory=dict)
    flipped: bool = False                    # the intake reversed the triangles (inward mesh)
    genus: Optional[int] = None
    boundary_loops: List[np.ndarray] = field(default_factory=list)  # open meshes: vertex loops
    notes: List[str] = field(default_factory=list)
    fingerprint: str = ""
    has_ngons: bool = False
    generated_uv: Optional[str] = None       # name of the cube projection written for it
    dest: Any = None                         # the bpy object the outputs are written on
    dest_name: str = ""

    @classmethod
    def from_mesh_data(cls, name, matrix, d):
        """From blender_io.read_map_mesh's dict (keys named like the fields)."""
        keys = ("V", "F", "tri_loops", "tri_polygon", "num_polygons", "loop_start", "loop_total",
                "loop_vertex", "evaluated", "same_topology", "uv_layers", "vertex_groups")
        return cls(name=name, matrix=np.asarray(matrix, dtype=np.float64),
                   **{k: d[k] for k in keys if k in d})

    def orient(self, flipped):
        """Reverses the triangles when the intake found the mesh inward (`flipped`) and sets
        the fingerprint the stored correspondence is checked against."""
        self.flipped = bool(flipped)
        F = np.ascontiguousarray(self.F, dtype=np.int32)
        tl = np.asarray(self.tri_loops, dtype=np.int64)
        if self.flipped:
            F = np.ascontiguousarray(F[:, [0, 2, 1]])
            tl = tl[:, [0, 2, 1]]
        self.F, self.tri_loops = F, tl
        self.fingerprint = fingerprint(self.V, F)
        self.has_ngons = bool(np.any(np.asarray(self.loop_total) > 3))
        return self

    def corner_uvs(self, loop_uv):
        """(m,3,2) UV of every triangle corner, in the order of F."""
        return np.asarray(loop_uv, dtype=np.float64)[self.tri_loops]

    # Read access by key, for code written against the earlier dict form of a side.
    def __getitem__(self, key):
        try:
            return getattr(self, key)
        except AttributeError:
            raise KeyError(key) from None

    def get(self, key, default=None):
        return getattr(self, key, default)
