"""Compute Map on open meshes (docs/open_surfaces.md): a disk pair writes the closed maps'
outputs and draws the boundary loops as curves; mismatched (g, b) is refused naming both."""
import bpy
import numpy as np

import helpers
from helpers import run, select
from test_map import _check_outputs, _check_uvs, _mapping


def cap(n, bump=0.0):
    """A spherical cap (hemisphere, rim at z = 0) as a polar grid with a centre vertex; `bump`
    adds an asymmetric bulge so the shape has one best rotation (samples/shapes.h spherical_cap)."""
    return helpers.sm().shapes.spherical_cap(n, bump)


def tube(around=24, rows=6):
    V = [[np.cos(2 * np.pi * j / around), np.sin(2 * np.pi * j / around), i / rows]
         for i in range(rows + 1) for j in range(around)]
    F = []
    for i in range(rows):
        for j in range(around):
            a, b = i * around + j, i * around + (j + 1) % around
            F += [[a, b, b + around], [a, b + around, a + around]]
    return np.array(V, float), np.array(F)


def _disk_pair():
    a = helpers.mesh_object("Dome", *cap(8, bump=0.3), (-3, 0, 0))
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=20, y_subdivisions=20, size=2, location=(3, 0, 0))
    b = bpy.context.active_object                    # quads
    b.name = "Square"
    helpers.set_loop_uvs(a, "Box", helpers.box_uvs(a))
    select([a, b], b)
    return a, b


def test_open_disk_pair_writes_every_output_and_draws_the_boundary():
    a, b = _disk_pair()
    res, err = run("compute_map")
    assert res == {'FINISHED'}, err
    status = bpy.context.scene.surfmap.map_status
    assert "open surfaces (genus 0 with 1 boundary loop): disk" in status, status
    _check_outputs(a, b, 0, uv_names=())
    # UVs: no transferred triangle turns over. The square's corner "ears" (triangles with
    # all three corners on the boundary) map onto three points of the dome's rim, which the
    # box projection sends onto one line: zero area, allowed there only.
    Ft, Lt = helpers.triangles_of(b)
    sq = helpers.coords(b)
    on_edge = np.abs(np.max(np.abs(sq[:, :2]), axis=1) - 1) < 1e-6
    ears = np.all(on_edge[Ft], axis=1)
    A = _mapping().signed_uv_areas(helpers.loop_uv_array(b, "surfmap Box")[Lt])
    assert np.all(A > 0) or (np.all(A[A <= 0] > -1e-12) and np.all(ears[A <= 0])), A[A <= 0]
    _check_uvs(a, b, "Box", max_flipped=ears.sum() / len(Ft))
    # Boundary onto boundary: the morph puts the dome's rim on the square's edge and no
    # interior vertex there; the square's edge goes onto the rim (z = 0 of the dome).
    rim = np.abs(helpers.coords(a)[:, 2]) < 1e-9
    key = a.data.shape_keys.key_blocks["surfmap to Square"]
    co = np.empty(len(a.data.vertices) * 3)
    key.data.foreach_get("co", co)
    co = co.reshape(-1, 3)
    edge = lambda P: np.abs(np.max(np.abs(P[:, :2]), axis=1) - 1) < 1e-6
    assert np.all(edge(co[rim])) and not np.any(edge(co[~rim]))
    key = b.data.shape_keys.key_blocks["surfmap to Dome"]
    co = np.empty(len(b.data.vertices) * 3)
    key.data.foreach_get("co", co)
    co = co.reshape(-1, 3)
    assert np.all(np.abs(co[edge(sq), 2]) < 1e-6) and np.all(co[~edge(sq), 2] > 1e-6)
    # The boundary loops as curves, one per object, through the boundary vertices.
    for ob, ring in ((a, rim), (b, edge(sq))):
        curves = helpers.loop_curves(ob)
        assert [c.name for c in curves] == [f"{ob.name} boundary 1"], [c.name for c in curves]
        pts = np.array([p.co[:3] for p in curves[0].data.splines[0].points])
        assert len(pts) == int(ring.sum()) and curves[0].data.splines[0].use_cyclic_u
        V = helpers.coords(ob)
        d = np.linalg.norm(pts[:, None, :] - V[ring][None, :, :], axis=2).min(axis=1)
        assert d.max() < 1e-6


def test_open_disk_pair_holds_an_interior_landmark():
    """One interior landmark on a disk pair (the core pins the disk's Moebius group with it):
    the source vertex's stored image is the target vertex."""
    a, b = _disk_pair()
    Va, Vb = helpers.coords(a), helpers.coords(b)
    p = int(np.argmin(np.linalg.norm(Va[:, :2] - [0.3, 0.2], axis=1)))
    q = int(np.argmin(np.linalg.norm(Vb[:, :2] - [0.4, -0.3], axis=1)))
    bpy.context.scene.surfmap.landmark_mode = 'GROUPS'
    a.vertex_groups.new(name="lm_spot").add([p], 1.0, 'REPLACE')
    b.vertex_groups.new(name="lm_spot").add([q], 1.0, 'REPLACE')
    try:
        res, err = run("compute_map")
    finally:
        bpy.context.scene.surfmap.landmark_mode = 'NONE'
    assert res == {'FINISHED'}, err
    assert "lm_spot" in bpy.context.scene.surfmap.map_status
    face = a.data.attributes["surfmap_map_face"].data[p].value
    bary = np.array(a.data.attributes["surfmap_map_bary"].data[p].vector)
    at = _mapping().points_at(Vb, helpers.triangles_of(b)[0], [face], [bary])[0]
    assert np.linalg.norm(at - Vb[q]) < 1e-5, (at, Vb[q])


def test_open_pairs_with_different_topology_are_refused_naming_both():
    a = helpers.mesh_object("Dome", *cap(6), (-3, 0, 0))
    b = helpers.mesh_object("Tube", *tube(), (3, 0, 0))
    select([a, b], b)
    before = helpers.scene_snapshot()
    res, err = run("compute_map")
    assert res != {'FINISHED'}
    assert "'Dome' has genus 0 with 1 boundary loop" in err and "'Tube' has genus 0 with 2 boundary loops" in err, err
    assert helpers.scene_snapshot() == before
    c = helpers.torus("Ring", 1.0, 0.4, (0, 3, 0))
    select([a, c], c)
    res, err = run("compute_map")
    assert res != {'FINISHED'} and "genus 0 with 1 boundary loop" in err and "genus 1 (closed)" in err, err


def test_open_annulus_pair_maps_loops_onto_loops():
    V, F = tube(24, 6)
    a = helpers.mesh_object("Short", V, F, (-3, 0, 0))
    V2, F2 = tube(30, 10)
    V2[:, 2] *= 2.0
    b = helpers.mesh_object("Tall", V2, F2, (3, 0, 0))
    helpers.set_loop_uvs(a, "Box", helpers.box_uvs(a))
    select([a, b], b)
    res, err = run("compute_map")
    assert res == {'FINISHED'}, err
    status = bpy.context.scene.surfmap.map_status
    assert "genus 0 with 2 boundary loops): annulus" in status and " 0 flipped" in status, status
    _check_outputs(a, b, 0, uv_names=("Box",))
    # Each loop onto a loop: the morph keeps z = 0 and z = 1 on z = 0 and z = 2 (in some order).
    key = a.data.shape_keys.key_blocks["surfmap to Tall"]
    co = np.empty(len(a.data.vertices) * 3)
    key.data.foreach_get("co", co)
    z = co.reshape(-1, 3)[:, 2].copy()
    for level in (0.0, 1.0):
        ring = np.abs(V[:, 2] - level) < 1e-9
        assert np.ptp(z[ring]) < 1e-6 and min(abs(z[ring][0]), abs(z[ring][0] - 2.0)) < 1e-6
    for ob in (a, b):
        assert [c.name for c in helpers.loop_curves(ob)] == [f"{ob.name} boundary 1", f"{ob.name} boundary 2"]
    # The panel's Boundary Loops '1 0' maps each loop onto the other one.
    settings = bpy.context.scene.surfmap
    settings.boundary_pairing = "1 0"
    res, err = run("compute_map")
    assert res == {'FINISHED'}, err
    assert "boundary loops [1, 0]" in settings.map_status, settings.map_status
    a.data.shape_keys.key_blocks["surfmap to Tall"].data.foreach_get("co", co)
    z_swapped = co.reshape(-1, 3)[:, 2]
    ring = np.abs(V[:, 2]) < 1e-9
    assert abs(abs(z_swapped[ring][0] - z[ring][0]) - 2.0) < 1e-6, (z[ring][:3], z_swapped[ring][:3], [k.name for k in a.data.shape_keys.key_blocks])
    for bad, words in (("0 0", "boundary pairing [0, 0]"), ("one", "Boundary Loops 'one'")):
        settings.boundary_pairing = bad
        res, err = run("compute_map")
        assert res != {'FINISHED'} and words in (err or ""), (bad, err)
    # Auto ticked again: the text is kept but not used (loop i onto loop i).
    settings.boundary_pairing_auto = True
    res, err = run("compute_map")
    assert res == {'FINISHED'}, err
    assert "boundary loops [0, 1]" in settings.map_status and settings.boundary_pairing == "one"


def test_panel_shows_auto_for_the_pairings_not_minus_one():
    """Automatic handle and boundary pairings are 'Auto' check boxes (the -1 / empty text they
    stand for is not drawn); unticked, the number or the loops are drawn beside them."""
    from test_addon import draw_all_panels
    settings = bpy.context.scene.surfmap
    assert settings.homotopy == -1 and settings.homotopy_auto and settings.boundary_pairing_auto
    log = draw_all_panels()
    drawn = [x[1] for x in log if x[0] == "prop"]
    assert "homotopy_auto" in drawn and "boundary_pairing_auto" in drawn
    assert "homotopy" not in drawn and "boundary_pairing" not in drawn
    rna = settings.bl_rna.properties
    assert rna["homotopy_auto"].name == rna["boundary_pairing_auto"].name == "Auto"
    # Unticked: the last run's chosen pairing to start with, drawn beside the box.
    settings.chosen_candidate = 3
    settings.homotopy_auto = False
    assert settings.homotopy == 3 and not settings.homotopy_auto
    settings.boundary_pairing = "1 0"          # typing loops unticks Auto
    assert not settings.boundary_pairing_auto
    drawn = [x[1] for x in draw_all_panels() if x[0] == "prop"]
    assert "homotopy" in drawn and "boundary_pairing" in drawn
    settings.homotopy_auto = True
    assert settings.homotopy == -1
    settings.boundary_pairing = ""             # cleared: automatic again
    assert settings.boundary_pairing_auto
    settings.chosen_candidate = -1


def _pants(subdivisions=3, squash=1.0):
    """An icosphere with three caps of different sizes removed (genus 0, 3 boundary loops)."""
    import bmesh
    bm = bmesh.new()
    bmesh.ops.create_icosphere(bm, subdivisions=subdivisions, radius=1.0)
    V = np.array([v.co[:] for v in bm.verts])
    bm.verts.index_update()
    F = np.array([[v.index for v in f.verts] for f in bm.faces])
    bm.free()
    dirs = np.array([[1, 0, 0.3], [-0.5, 0.866, -0.2], [-0.4, -0.8, 0.5]])
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    c = V[F].mean(axis=1)
    c /= np.linalg.norm(c, axis=1)[:, None]
    F = F[np.all(c @ dirs.T < np.array([0.8, 0.85, 0.75]), axis=1)]
    used = np.unique(F)
    remap = -np.ones(len(V), int)
    remap[used] = np.arange(len(used))
    V = V[used]
    V[:, 0] += squash * 0.3 * V[:, 1] ** 2    # a bend
    return V, remap[F]


def test_open_pants_pair_maps_through_the_doubles():
    """(0, 3): Compute Map goes through the doubles (docs/open_surfaces.md "Doubling"), with the
    panel's Boundary Loops as the pairing; every output is written, loops onto loops."""
    Vs, Fs = _pants(squash=0.0)
    Vt, Ft = _pants(squash=1.0)
    a = helpers.mesh_object("Pants", Vs, Fs, (-3, 0, 0))
    b = helpers.mesh_object("Bent", Vt, Ft, (3, 0, 0))
    helpers.set_loop_uvs(a, "Box", helpers.box_uvs(a))
    select([a, b], b)
    settings = bpy.context.scene.surfmap
    settings.boundary_pairing = "0 1 2"
    res, err = run("compute_map")
    assert res == {'FINISHED'}, err
    status = settings.map_status
    assert "genus 0 with 3 boundary loops): double" in status and " 0 flipped" in status, status
    assert "boundary loops [0, 1, 2] (preserving, given)" in status, status
    _check_outputs(a, b, 0, uv_names=("Box",))
    for ob in (a, b):
        assert [c.name for c in helpers.loop_curves(ob)] == [f"{ob.name} boundary {k}" for k in (1, 2, 3)]
    # The morph puts each boundary vertex of the pants on the bent copy's boundary.
    key = a.data.shape_keys.key_blocks["surfmap to Bent"]
    co = np.empty(len(a.data.vertices) * 3)
    key.data.foreach_get("co", co)
    co = co.reshape(-1, 3)
    def boundary_edges(F):
        e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
        u, n = np.unique(e, axis=0, return_counts=True)
        return u[n == 1]
    Es, Et = boundary_edges(Fs), boundary_edges(Ft)
    A, B = Vt[Et[:, 0]], Vt[Et[:, 1]]
    P = co[np.unique(Es)]
    t = np.clip(np.einsum("pij,ij->pi", P[:, None] - A[None], B - A) / np.einsum("ij,ij->i", B - A, B - A), 0, 1)
    assert np.linalg.norm(A[None] + t[..., None] * (B - A)[None] - P[:, None], axis=2).min(axis=1).max() < 1e-6


def test_open_head_and_mask_uvs_without_flips():
    """An open head (genus 0, the neck open) and an open face mask (docs/open_surfaces.md "In
    Blender: an open head and a mask"): the mask's box UVs transferred onto the head by Compute
    Map with no flipped triangle, ears included, and none straddling a seam but ears given their
    own shape; both boundaries drawn as curves. The head's ears (faces with three corners on its neck loop) take three
    points of the mask's rim: before their images were slid along the rim (map/ear_images.h), 8
    of the 24 turned over and their transferred UVs flipped. Blender's Data Transfer on the same
    pair (Nearest Face Interpolated) is counted beside it, for the record."""
    Vm, Fm = helpers.open_mask(5)
    Vh, Fh = helpers.open_head(4)
    mask = helpers.mesh_object("Mask", Vm, Fm, (-2.5, 0, 0))
    head = helpers.mesh_object("Head", Vh, Fh, (0, 0, 0))
    helpers.set_loop_uvs(mask, "Box", helpers.box_uvs(mask))
    select([mask, head], head)
    res, err = run("compute_map")
    assert res == {'FINISHED'}, err
    status = bpy.context.scene.surfmap.map_status
    assert "open surfaces (genus 0 with 1 boundary loop): disk" in status, status
    Ft, Lt = helpers.triangles_of(head)
    A = _mapping().signed_uv_areas(helpers.loop_uv_array(head, "surfmap Box")[Lt])
    edges = np.sort(np.concatenate([Ft[:, [0, 1]], Ft[:, [1, 2]], Ft[:, [2, 0]]]), axis=1)
    e, n = np.unique(edges, axis=0, return_counts=True)
    on_b = np.zeros(len(Vh), bool)
    on_b[e[n == 1].ravel()] = True
    ears = np.all(on_b[Ft], axis=1)
    assert ears.sum() >= 20                      # the check has ears to get wrong
    assert np.all(A > 0), f"{int(np.sum(A <= 0))} flipped UV triangles ({int(np.sum((A <= 0) & ears))} ears)"
    # Straddling (a UV edge far longer than its preimages are apart): only ears whose UVs were
    # given their own shape (no point of the mask's rim in the chart rights them) can be.
    flipped, straddling, _ = _check_uvs(mask, head, "Box", max_straddling=ears.sum() / len(Ft))
    assert flipped == 0
    for ob in (head, mask):
        assert [c.name for c in helpers.loop_curves(ob)] == [f"{ob.name} boundary 1"]
    # Data Transfer on a copy of the head: the same layer from the same mask.
    dt = head.copy()
    dt.data = head.data.copy()
    bpy.context.scene.collection.objects.link(dt)
    mod = dt.modifiers.new("DataTransfer", 'DATA_TRANSFER')
    mod.object = mask
    mod.use_object_transform = False
    mod.use_loop_data = True
    mod.data_types_loops = {'UV'}
    mod.loop_mapping = 'POLYINTERP_NEAREST'
    mod.layers_uv_select_src = 'ALL'
    mod.layers_uv_select_dst = 'NAME'
    dt.data.uv_layers["surfmap Box"].data.foreach_set("uv", np.zeros(2 * len(dt.data.loops), np.float32))
    dt.data.uv_layers["surfmap Box"].name = "Box"
    dg = bpy.context.evaluated_depsgraph_get()
    me = dt.evaluated_get(dg).to_mesh()
    uv = np.empty(2 * len(me.loops))
    me.uv_layers["Box"].data.foreach_get("uv", uv)
    dt.evaluated_get(dg).to_mesh_clear()
    theirs = int(np.sum(_mapping().signed_uv_areas(uv.reshape(-1, 2)[Lt]) <= 0))
    print(f"    mask -> head UVs: Compute Map 0 flipped, Data Transfer {theirs} flipped of {len(Ft)}")


def test_show_cut_loops_draws_an_open_pairs_boundary():
    """Show Cut Loops (the Cut Loops panel) on an open pair draws each object's boundary loops as
    curves, as Compute Map does ('<object> boundary k', through the boundary vertices, cyclic),
    and says so in the panel's status; before, the intake refused the boundary ("boundary
    loops") and nothing was drawn. A closed object beside an open one keeps its cut loops."""
    Vs, Fs = _pants(squash=0.0)
    Vt, Ft = _pants(squash=1.0)
    a = helpers.mesh_object("Pants", Vs, Fs, (-3, 0, 0))
    b = helpers.mesh_object("Bent", Vt, Ft, (3, 0, 0))
    select([a, b], b)
    res, err = run("show_cut_loops")
    assert res == {'FINISHED'}, err
    status = bpy.context.scene.surfmap.status
    for ob, V, F in ((a, Vs, Fs), (b, Vt, Ft)):
        assert f"'{ob.name}': genus 0 with 3 boundary loops, drawn as 3 curves" in status, status
        curves = helpers.loop_curves(ob)
        assert [c.name for c in curves] == [f"{ob.name} boundary {k}" for k in (1, 2, 3)]
        e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
        u, n = np.unique(e, axis=0, return_counts=True)
        ring = np.unique(u[n == 1])
        pts = np.concatenate([np.array([p.co[:3] for p in c.data.splines[0].points]) for c in curves])
        assert all(c.data.splines[0].use_cyclic_u for c in curves)
        assert len(pts) == len(ring)
        assert np.linalg.norm(pts[:, None] - V[ring][None], axis=2).min(axis=1).max() < 1e-6
    # A closed torus beside an open mesh: its cut loops as before.
    helpers.reset_scene()
    t = helpers.torus("Torus", location=(3, 0, 0))
    c = helpers.mesh_object("Pants", Vs, Fs, (-3, 0, 0))
    select([c, t], t)
    res, err = run("show_cut_loops")
    assert res == {'FINISHED'}, err
    assert sorted(x.name for x in helpers.loop_curves(t)) == ["Torus a1", "Torus b1"]
    assert [x.name for x in helpers.loop_curves(c)] == [f"Pants boundary {k}" for k in (1, 2, 3)]
