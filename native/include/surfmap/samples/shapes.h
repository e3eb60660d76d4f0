#pragma once
// Procedural closed test surfaces: analytic tori of revolution, and smooth
// implicit shapes of any genus 1..8 in the spirit of the paper's models
// (vase, amphora, cup, polycube, n-hole torus), meshed by marching
// tetrahedra. Every generator returns a closed, manifold, one-component,
// outward-oriented (signed volume > 0) triangle mesh of the stated genus with
// no zero-area faces (except insert_degenerate_faces, which adds them on
// purpose); tests and benchmarks build their inputs from these.
#include <Eigen/Core>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap::samples {

/// Torus of revolution, major radius R > minor radius r > 0, n_major x n_minor
/// quad grid split into triangles (2*n_major*n_minor faces, n_major*n_minor
/// vertices, all exactly on (sqrt(x^2+y^2)-R)^2 + z^2 = r^2).
/// `connectivity_variant` changes the triangulation of the same vertex set
/// (0: all quads split along one diagonal; 1: alternating diagonals in a
/// checkerboard; 2: every other ring offset by half a cell; other values: a
/// seeded random diagonal per quad), so the same surface gets a different F.
/// Throws InputError on R <= r, r <= 0, n_major < 3 or n_minor < 3.
TriMesh torus_of_revolution(double R, double r, int n_major, int n_minor,
                            int connectivity_variant = 0);

/// Smooth closed surface of genus n (n = 1..8): n holes in a row (n <= 4) or
/// a wheel with n spokes (n >= 5), the zero set of an implicit function meshed
/// by marching tetrahedra on a grid of `resolution` cells along the longest
/// axis. smooth=true improves the triangles (tangential relaxation, edge flips
/// and projection back onto the level set, never flipping a triangle);
/// smooth=false leaves the raw marching-tets output with its slivers (the
/// "ugly mesh" the tests want). #V grows like resolution^2 (about 7k-9k
/// vertices at 32, 25k-35k at 64, 250k at 200, 1M at 400). Every implicit
/// shape is resolved from resolution 32 up; below that thin parts may not be,
/// and the generator throws Error (it always checks closedness, manifoldness,
/// one component, genus and orientation of what it returns).
TriMesh n_hole_torus(int n, int resolution = 64, bool smooth = true);

/// Wheel with `spokes` spokes (genus = spokes, 3..32): a rim and spokes of
/// radius 0.3 meeting at the hub, meshed like n_hole_torus (which uses the
/// same wheel for n >= 5). The rim radius is 3 up to 8 spokes and 3 spokes/8
/// beyond, so resolution must grow with the spokes to resolve them
/// (about 12 cells per unit length: 64 at 11 spokes, 96 at 24). Throws
/// InputError outside 3..32, Error when the grid does not resolve it.
TriMesh wheel(int spokes, int resolution = 64, bool smooth = true);

/// Vase with two handles (genus 2).
TriMesh vase(int resolution = 64, bool smooth = true);
/// Amphora: tall neck, pointed foot, two handles from neck to shoulder
/// (genus 2, proportions unlike the vase).
TriMesh amphora(int resolution = 64, bool smooth = true);
/// Squat cup/teapot-like body with `handles` handles around it (genus =
/// handles, 1..8).
TriMesh cup(int handles = 1, int resolution = 64, bool smooth = true);
/// Polycube-like rounded block with `holes` square through-holes in a row
/// (genus = holes, 1..8).
TriMesh polycube(int holes = 3, int resolution = 64, bool smooth = true);

/// Moves every vertex by a random tangential offset of `amplitude` times the
/// local mean edge length (seeded, deterministic). A move that would flip or
/// degenerate an incident triangle is shrunk, so the result stays embedded
/// and consistently oriented. Requires 0 <= amplitude < 0.3.
TriMesh jitter(const TriMesh& mesh, double amplitude, unsigned seed);

/// Inversion in the sphere with centre c and radius rho:
/// x -> c + rho^2 (x - c) / |x - c|^2, a conformal copy of the mesh
/// (docs/method.md section 3). c must lie outside the surface's vertices (throws
/// InputError if it coincides with one). Faces are reversed when c is outside
/// the enclosed solid, so the result stays outward-oriented.
TriMesh sphere_inversion(const TriMesh& mesh, const Eigen::Vector3d& c, double rho);

/// Genus-0 unit sphere: an icosahedron subdivided `subdivisions` times
/// (10*4^s + 2 vertices), vertices projected onto the sphere.
TriMesh sphere(int subdivisions = 3);

/// Open disk: the spherical cap z >= 0 of the unit sphere (a hemisphere,
/// rim at z = 0) as a polar grid, a centre vertex and `rings` rings of
/// 6 x rings vertices each (1 + 6 rings² vertices); `bump` lifts z by
/// bump * x * z, an asymmetric bulge so the shape has one best rotation.
/// Throws InputError on rings outside 1..1000.
TriMesh spherical_cap(int rings, double bump = 0.0);

/// Closed sphere with slivers: a UV sphere (`rings` x `segments`, pole fans)
/// stretched `stretch`:1 along z (2 + (rings - 1) segments vertices); 30 x
/// 200 at 10:1 has corner angles down to 1 degree. Throws InputError on
/// rings < 2, segments < 3 or stretch <= 0.
TriMesh stretched_uv_sphere(int rings, int segments, double stretch);

/// Closed sphere, long, bent and tapered (issue 13 item 5): the UV sphere of
/// stretched_uv_sphere (`rings` x `segments`, stretched `stretch`:1 along z,
/// z in [-stretch, stretch]), then bent, x += bend z² / stretch, and
/// tapered, y scaled by 1 + z / (2 stretch) (half as thick at the bottom as
/// at the equator, 1.5 times at the top). The crowded ends of its conformal
/// sphere are not antipodal, and 30 x 200 at 10:1 has corner angles of about
/// 1 degree. Throws InputError on rings < 2, segments < 3, stretch < 1 or a
/// bend outside [0, 1].
TriMesh bent_tapered_sphere(int rings, int segments, double stretch, double bend = 0.3);

/// Genus-0 implicit "peanut" (two overlapping spheres blended smoothly),
/// meshed like the shapes above; smooth=false keeps the raw marching-tets
/// slivers. Gives the robustness benchmark a genus-0 raw mesh.
TriMesh peanut(int resolution = 64, bool smooth = true);

/// CAD-like part: a rectangular plate (x in [0, holes], y in [0, 1], z in
/// [0, thickness]) with `holes` round through-holes of radius 0.3, one per
/// unit cell, tessellated the way CAD exporters do: each planar face as long
/// fans of thin triangles from the cell corners to `segments` points on each
/// hole's rim, each wall (hole and outer) as one strip of two triangles per
/// segment. Genus = holes; 4 (holes + 1) + 2 holes segments vertices.
/// thickness 0.1 gives a plate, 1 or more a block with long thin hole walls.
/// Throws InputError on holes < 1, segments < 8 or not a multiple of 4,
/// thickness <= 0.
TriMesh cad_plate(int holes = 2, int segments = 64, double thickness = 0.1);

/// Inserts `count` exactly degenerate faces: for each of `count` edges (a, b)
/// (seeded choice, no two in the same face), a new vertex m at a + t (b - a)
/// splits one face (a, b, c) into (a, m, c), (m, b, c) and the zero-area
/// face (m, a, b) closes the gap to the other face at (a, b). t = 0 puts m
/// exactly on a (a zero-length edge, two faces of exactly zero area);
/// 0 < t < 1 makes m collinear with a and b (angles of 0 and 180 degrees).
/// The result is still closed, manifold and of the same genus; intake accepts
/// it through intrinsic mollification. Requires 0 <= t < 1 and
/// count <= #F / 8.
TriMesh insert_degenerate_faces(const TriMesh& mesh, int count, double t, unsigned seed);

/// A needle tip like those of g1_twirl: vertex `v` is raised by `height`
/// along its area-weighted normal, and its lowest-numbered neighbour n moves
/// up to `gap` of the way back from the tip (n = tip + gap (n - tip)), so the
/// tip has a small cone angle and one neighbour much closer than the rest.
/// Intrinsic Delaunay then wants the tip to keep a single edge (to n; see
/// geometry/intrinsic_delaunay.h, min_degree). Same connectivity as `mesh`.
/// Throws InputError on a bad vertex, height <= 0 or gap outside (0, 1).
TriMesh needle(const TriMesh& mesh, int v, double height, double gap);

/// A long finger like the legs of g1_camel: the star of vertex `v` extruded
/// along its area-weighted normal into a tube of `segments` rings of v's link
/// (each a copy of the link moved by length / segments), capped by v's star
/// with v at `length` plus half the link's mean radius. A harmonic map into a
/// flat torus squeezes such a tube by about exp(-2 pi length / circumference)
/// (docs/robustness.md, "The source side"). Same genus; adds
/// segments x #link vertices. Throws InputError on a bad vertex, length <= 0
/// or segments < 1.
TriMesh finger(const TriMesh& mesh, int v, double length, int segments);

}  // namespace surfmap::samples
