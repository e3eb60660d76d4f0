"""surfmap.show_cut_loops on good and bad selections."""
import bpy
import numpy as np

import helpers
from helpers import run_op, select


def _check_object_loops(ob, genus, triangles=True):
    """Properties a correct result must have for one object. With polygons (triangles=False)
    loop edges that are triangulation diagonals cannot be seams, so the seams are only checked
    to lie on the loops."""
    curves = helpers.loop_curves(ob)
    names = sorted(f"{ob.name} {'ab'[k % 2]}{k // 2 + 1}" for k in range(2 * genus))
    assert [c.name for c in curves] == names, ([c.name for c in curves], names)
    coll = bpy.data.collections.get(f"{ob.name} loops")
    assert coll is not None and sorted(o.name for o in coll.objects) == names
    assert coll in bpy.context.scene.collection.children_recursive[:]
    diag = float(np.linalg.norm(np.ptp(np.array([v.co for v in ob.data.vertices]), axis=0)))
    starts = []
    for c in curves:
        assert c.parent == ob and c.type == 'CURVE'
        assert c.data.bevel_depth > 0 and len(c.data.materials) == 1
        sp = c.data.splines[0]
        assert sp.use_cyclic_u and len(sp.points) >= 3
        pts = [p.co.xyz for p in sp.points]
        starts.append(np.array(pts[0]))
        # every curve point lies on the object's surface (local space)
        for p in pts[:: max(1, len(pts) // 25)]:
            ok, loc, _, _ = ob.closest_point_on_mesh(p)
            assert ok and (loc - p).length < 1e-5 * diag, (c.name, (loc - p).length)
        # the curve follows the object's transform
        assert np.allclose(np.array(c.matrix_world), np.array(ob.matrix_world), atol=1e-6)
    # all loops start at the same base vertex, which is a mesh vertex
    for s in starts:
        assert np.allclose(s, starts[0], atol=1e-9)
    co = np.array([v.co for v in ob.data.vertices])
    assert np.min(np.linalg.norm(co - starts[0], axis=1)) < 1e-6
    # pair colours: a_i and b_i differ, and every loop has its own material colour
    cols = [tuple(c.data.materials[0].diffuse_color) for c in curves]
    assert len(set(cols)) == 2 * genus
    # seams: the union of the 2g loops, a cut graph through the base vertex:
    # connected, no dangling edge, Euler characteristic 1 - 2g, cutting keeps the faces
    # in one piece (a disk).
    verts, edges = helpers.seam_graph(ob)
    assert edges, "no seams marked"
    if not triangles:
        # seams are the unrefined loops; the drawn (refined) loops detour from them only
        # locally, around vertices the loops share: every seam vertex is near a curve
        on_loops = np.array([p.co.xyz for c in curves for p in c.data.splines[0].points])
        longest = max((ob.data.vertices[e.vertices[0]].co - ob.data.vertices[e.vertices[1]].co)
                      .length for e in ob.data.edges)
        for v in verts:
            d = np.min(np.linalg.norm(on_loops - co[v], axis=1))
            assert d <= 2 * longest, f"seam vertex {v} is {d} from the loops"
        return
    deg = {}
    for a, b in edges:
        deg[a] = deg.get(a, 0) + 1
        deg[b] = deg.get(b, 0) + 1
    assert min(deg.values()) >= 2, "a seam edge dangles"
    assert len(verts) - len(edges) == 1 - 2 * genus, (len(verts), len(edges))
    base = int(np.argmin(np.linalg.norm(co - starts[0], axis=1)))
    assert base in deg and deg[base] >= 2 * genus, (base, deg.get(base))
    assert helpers.faces_connected_across_non_seams(ob)


def _pair(make_a, make_b, genus):
    a = make_a("Source", (-3, 0, 0))
    b = make_b("Target", (3, 0, 0))
    select([a, b], b)
    before = {o.name: helpers.mesh_snapshot(o) for o in (a, b)}
    res, err = run_op()
    assert res == {'FINISHED'}, err
    for o in (a, b):
        co, faces, _ = helpers.mesh_snapshot(o)
        assert co == before[o.name][0], "vertex coordinates changed"
        assert faces == before[o.name][1], "faces changed"
        _check_object_loops(o, genus)
    status = bpy.context.scene.surfmap.status
    assert f"genus {genus}" in status and "'Source'" in status and "'Target'" in status
    assert "a1" in status
    return a, b


def test_genus1_pair():
    _pair(lambda n, l: helpers.torus(n, 1.0, 0.5, l), lambda n, l: helpers.torus(n, 1.5, 0.5, l), 1)


def test_genus2_pair():
    _pair(helpers.double_torus, helpers.double_torus, 2)


def test_run_twice_replaces_loops():
    a, b = _pair(lambda n, l: helpers.torus(n, 1.0, 0.5, l),
                 lambda n, l: helpers.torus(n, 1.5, 0.5, l), 1)
    seams_before = helpers.seam_graph(b)
    bpy.context.scene.surfmap.target_base_vertex = 7
    res, err = run_op()
    assert res == {'FINISHED'}, err
    for o in (a, b):
        _check_object_loops(o, 1)
    assert len(bpy.data.curves) == 4 and len(bpy.data.collections) == 2
    assert not any(o.name.endswith(".001") for o in bpy.data.objects)
    # base vertex 7 was used for the target: its loops start at vertex 7
    p0 = helpers.loop_curves(b)[0].data.splines[0].points[0].co.xyz
    assert (p0 - b.data.vertices[7].co).length < 1e-9
    # the old seams were replaced, not added to: still a cut graph (checked above)
    assert helpers.seam_graph(b) != seams_before


def test_user_seams_kept():
    ob = helpers.torus("T")
    ob.data.edges[0].use_seam = True  # the user's own seam
    select([ob], ob)
    res, err = run_op()
    assert res == {'FINISHED'}, err
    assert ob.data.edges[0].use_seam
    assert len(helpers.loop_curves(ob)) == 2


def test_single_object_and_blender_quads():
    bpy.ops.mesh.primitive_torus_add(major_segments=32, minor_segments=12)
    ob = bpy.context.active_object
    assert all(len(p.vertices) == 4 for p in ob.data.polygons)
    before = helpers.mesh_snapshot(ob)
    select([ob], ob)
    res, err = run_op()
    assert res == {'FINISHED'}, err
    co, faces, _ = helpers.mesh_snapshot(ob)
    assert co == before[0] and faces == before[1]
    _check_object_loops(ob, 1, triangles=False)


def test_genus_mismatch_cancels():
    a = helpers.torus("Ring")
    b = helpers.double_torus("Pretzel", (3, 0, 0))
    select([a, b], b)
    before = helpers.scene_snapshot()
    res, err = run_op()
    assert res is None and err is not None
    assert "'Ring'" in err and "'Pretzel'" in err, err
    assert "genus 1" in err and "genus 2" in err, err
    assert helpers.scene_snapshot() == before


def _expect_error(objs, active, *words):
    select(objs, active)
    before = helpers.scene_snapshot()
    res, err = run_op()
    assert res is None and err is not None, res
    low = err.lower()
    for w in words:
        assert w.lower() in low, (w, err)
    assert helpers.scene_snapshot() == before
    return err


def test_open_mesh_draws_its_boundary():
    """An open mesh has no cut loops: its boundary loop is drawn instead, as Compute Map draws
    it (docs/open_surfaces.md; before, the boundary was refused)."""
    bpy.ops.mesh.primitive_cube_add()
    cube = bpy.context.active_object
    cube.name = "OpenBox"
    me = cube.data
    V = [tuple(v.co) for v in me.vertices]
    polys = [tuple(p.vertices) for p in me.polygons][1:]  # one face deleted
    ob = helpers.mesh_object("OpenBox2", V, [list(p) for p in polys])
    bpy.data.objects.remove(cube, do_unlink=True)
    select([ob], ob)
    res, err = helpers.run("show_cut_loops")
    assert res == {'FINISHED'}, err
    assert "'OpenBox2': genus 0 with 1 boundary loop, drawn as 1 curve" in bpy.context.scene.surfmap.status
    curves = helpers.loop_curves(ob)
    assert [c.name for c in curves] == ["OpenBox2 boundary 1"]
    assert len(curves[0].data.splines[0].points) == 4     # the deleted face's four corners


def test_non_manifold_cancels():
    # two closed tetrahedra sharing the edge (0,1): that edge has 4 faces, no boundary
    V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (0, -1, 0), (0, 0, -1)]
    F = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2],
         [0, 1, 4], [0, 5, 1], [1, 5, 4], [0, 4, 5]]
    ob = helpers.mesh_object("Fin", V, F)
    _expect_error([ob], ob, "'Fin'", "manifold")


def test_camera_selected_cancels():
    t = helpers.torus("T")
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    bpy.context.scene.collection.objects.link(cam)
    _expect_error([t, cam], t, "'Cam'", "not a mesh")
    # only the camera: the operator cannot even run, and says why
    select([cam], cam)
    assert not bpy.ops.surfmap.show_cut_loops.poll()
    res, err = run_op()
    assert res is None and "mesh" in err.lower(), err


def test_three_meshes_cancel():
    objs = [helpers.torus(f"T{i}", location=(3 * i, 0, 0)) for i in range(3)]
    _expect_error(objs, objs[0], "3 objects selected")


def test_genus0_cancels():
    bpy.ops.mesh.primitive_uv_sphere_add()
    ob = bpy.context.active_object
    _expect_error([ob], ob, f"'{ob.name}'", "genus 0")


def test_base_vertex_out_of_range_cancels():
    ob = helpers.torus("T")
    bpy.context.scene.surfmap.target_base_vertex = 10 ** 6
    _expect_error([ob], ob, "base vertex", "out of range")


def test_modifiers_use_evaluated_mesh():
    ob = helpers.torus("T")
    ob.modifiers.new("Subsurf", 'SUBSURF').levels = 1
    select([ob], ob)
    before = helpers.mesh_snapshot(ob)
    res, err = run_op()
    assert res == {'FINISHED'}, err
    assert helpers.mesh_snapshot(ob) == before  # no seams on the un-modified edges
    curves = helpers.loop_curves(ob)
    assert len(curves) == 2
    # the user is told that the modified mesh was used and seams were not marked
    status = bpy.context.scene.surfmap.status
    assert "modifiers" in status and "seams not marked" in status, status
    # the curves lie on the subdivided (evaluated) surface: its vertices include new ones
    ob_eval = ob.evaluated_get(bpy.context.evaluated_depsgraph_get())
    me = ob_eval.to_mesh()
    assert len(me.vertices) > len(ob.data.vertices)
    co = np.array([v.co for v in me.vertices])
    ob_eval.to_mesh_clear()
    p0 = np.array(curves[0].data.splines[0].points[0].co.xyz)
    assert np.min(np.linalg.norm(co - p0, axis=1)) < 1e-6
