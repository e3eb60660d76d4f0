"""Registration and the bpy-free helpers of the add-on."""
import addon_utils
import bpy
import numpy as np

import helpers


def _registered():
    return (hasattr(bpy.types, "SURFMAP_PT_main")
            and hasattr(bpy.types, "SURFMAP_OT_show_cut_loops")
            and all(hasattr(bpy.types, "SURFMAP_OT_" + op) for op in (
                "compute_map", "transfer_uvs", "create_morph", "paint_distortion"))
            and hasattr(bpy.types.Scene, "surfmap"))


def test_register_unregister_twice():
    assert _registered()
    for _ in range(2):
        addon_utils.disable("surface_map", default_set=True, handle_error=None)
        assert not _registered(), "classes left registered after disable"
        assert not hasattr(bpy.types.Scene, "surfmap")
        mod = addon_utils.enable("surface_map", default_set=True, handle_error=None)
        assert mod is not None and _registered()
    assert bpy.context.scene.surfmap.target_base_vertex == -1
    assert "surface_map" in bpy.context.preferences.addons


def test_bl_info_and_preferences():
    import surface_map
    assert surface_map.bl_info["blender"] == (3, 4, 0)
    prefs = bpy.context.preferences.addons["surface_map"].preferences
    assert prefs is not None and hasattr(prefs, "module_path")
    assert surface_map.properties.SURFMAP_AP_preferences.bl_idname == "surface_map"


def test_native_module_loads():
    from surface_map import native
    mod = native.load()
    assert mod is not None, native.error()
    assert native.error() == "" and native.origin()
    for name in ("inspect", "intake", "system_of_loops", "Error", "InputError"):
        assert hasattr(mod, name), name


class _OpProps:
    """Stands in for the operator properties layout.operator() returns."""

    def __init__(self, log, idname):
        self.__dict__["_log"], self.__dict__["_idname"] = log, idname

    def __setattr__(self, name, value):
        self._log.append(("op_prop", self._idname, name, value))


class _FakeLayout:
    """Records what a draw() function puts in the panel (no UI in background mode)."""

    def __init__(self, log):
        self.__dict__["log"] = log

    def __setattr__(self, name, value):   # use_property_split, scale_y, alignment, ...
        self.__dict__[name] = value

    def box(self):
        return self

    def column(self, align=False, **kw):
        return self

    def row(self, align=False, **kw):
        return self

    def split(self, factor=0.0, align=False):
        return self

    def grid_flow(self, **kw):
        return self

    def label(self, text="", icon='NONE'):
        self.log.append(("label", text))

    def prop(self, data, name, **kw):
        self.log.append(("prop", name))
        self.log.append(("prop_options", name, kw))   # (text=, toggle=, ...: test_panel)

    def operator(self, idname, **kw):
        self.log.append(("operator", idname))
        if "text" in kw:
            self.log.append(("button", idname, kw["text"]))
        return _OpProps(self.log, idname)

    def template_list(self, list_id, name, data, prop, active_data, active_prop, **kw):
        self.log.append(("list", list_id, prop))


class _FakePanel:
    def __init__(self):
        self.log = []
        self.layout = _FakeLayout(self.log)


def draw_all_panels(context=None):
    """The log of every Surface Map panel's draw() (the main panel, then its sub-panels whose
    poll() passes), as the sidebar shows them one under the other."""
    from surface_map import panel
    context = context or bpy.context
    fake = _FakePanel()
    for cls in panel.classes:
        if not issubclass(cls, bpy.types.Panel):
            continue
        if hasattr(cls, "poll") and not cls.poll(context):
            continue
        cls.draw(fake, context)
    return fake.log


def test_panel_shows_module_status_settings_and_button():
    from surface_map import native, panel
    assert panel.SURFMAP_PT_main.bl_category == "Surface Map"
    assert panel.SURFMAP_PT_main.bl_region_type == 'UI'
    p = _FakePanel()
    p.log = draw_all_panels()
    assert ("label", "Native module: loaded") in p.log
    assert ("operator", "surfmap.show_cut_loops") in p.log
    for op in ("compute_map", "transfer_uvs", "create_morph", "paint_distortion"):
        assert ("operator", "surfmap." + op) in p.log, op
    for name in ("homotopy_auto", "boundary_pairing_auto", "landmark_mode", "method", "tolerance_text", "write_uvs", "write_morph",
                 "write_distortion", "morph_space"):
        assert ("prop", name) in p.log, name
    for name in ("source_base_vertex", "target_base_vertex", "loop_bevel", "mark_seams"):
        assert ("prop", name) in p.log
    # module missing: the panel says so and shows why
    saved = native.load, native.error
    try:
        native.load = lambda *a, **k: None
        native.error = lambda: "no module named surfmap (searched /nowhere)"
        p = _FakePanel()
        p.log = draw_all_panels()
        assert ("label", "Native module: missing") in p.log
        text = " ".join(x[1] for x in p.log if x[0] == "label")
        assert "/nowhere" in text, text
        assert not bpy.ops.surfmap.show_cut_loops.poll()
    finally:
        native.load, native.error = saved


def test_triangulate_polygons_corner_mapping():
    from surface_map import cut_loops as core
    polys = [[0, 1, 2, 3], [3, 2, 4], [4, 5, 6, 7, 8]]
    F, tp, tc = core.triangulate_polygons(polys)
    assert F.shape == (2 + 1 + 3, 3)
    assert tp.tolist() == [0, 0, 1, 2, 2, 2]
    for t in range(len(F)):
        poly = polys[tp[t]]
        # every triangle corner maps back to the polygon corner holding the same vertex
        assert [poly[c] for c in tc[t]] == F[t].tolist()
    # each polygon's corners are all used
    for p, poly in enumerate(polys):
        assert set(tc[tp == p].ravel().tolist()) == set(range(len(poly)))
    try:
        core.triangulate_polygons([[0, 1]])
    except ValueError as e:
        assert "polygon 0" in str(e)
    else:
        raise AssertionError("a 2-gon must be rejected")


def test_points_on_surface_and_edges_along_loops():
    from surface_map import cut_loops as core
    # Two triangles of a square: 0=(0,0) 1=(1,0) 2=(1,1) 3=(0,1); refined vertex 4 is the
    # midpoint of edge (0,1), vertex 5 the centroid of face 0.
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    origin_face = np.array([0, 0, 0, 1, 0, 0])
    bary = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 1],
                     [0.5, 0.5, 0], [1 / 3, 1 / 3, 1 / 3]])
    P = core.points_on_surface(V, F, origin_face, bary)
    assert np.allclose(P[:4], V)
    assert np.allclose(P[4], [0.5, 0, 0]) and np.allclose(P[5], [2 / 3, 1 / 3, 0])
    # loop 0 -> 4 -> 1 -> 2 -> 5 -> 0: (0,1) covered fully in two halves, (1,2) fully,
    # 2 -> 5 -> 0 crosses face 0, so (0,2) is NOT along the loop.
    loops = [[0, 4, 1, 2, 5, 0]]
    assert core.original_edges_along_loops(loops, 4, F, origin_face, bary, V) == [(0, 1), (1, 2)]
    # only half of (0,1) covered -> not a seam
    assert core.original_edges_along_loops([[0, 4, 5, 0]], 4, F, origin_face, bary, V) == []
    assert core.loop_edges([[0, 1, 2, 0]]) == [(0, 1), (0, 2), (1, 2)]
    assert core.open_path([7, 1, 2, 7]) == [7, 1, 2]


def test_pair_colours():
    import colorsys
    from surface_map import cut_loops as core
    assert [core.loop_name(k) for k in range(6)] == ["a1", "b1", "a2", "b2", "a3", "b3"]
    cols = [core.pair_colour(k) for k in range(10)]
    assert len(set(cols)) == 10
    hsv = [colorsys.rgb_to_hsv(*core.srgb_from_linear(c)[:3]) for c in cols]
    hues = [h[0] for h in hsv]

    def hd(a, b):
        d = abs(a - b) % 1.0
        return min(d, 1 - d)
    for i in range(5):
        # a_i and b_i: same hue family
        assert hd(hues[2 * i], hues[2 * i + 1]) < 0.13
        # a_i and b_i still tell apart (brightness)
        ca = np.array(core.srgb_from_linear(cols[2 * i])[:3])
        cb = np.array(core.srgb_from_linear(cols[2 * i + 1])[:3])
        assert np.linalg.norm(ca - cb) > 0.4, (ca, cb)
        for j in range(i):
            # different handles: hues well apart
            assert hd(hues[2 * i], hues[2 * j]) > 0.08, (i, j)


def test_genus_check_messages():
    from surface_map import cut_loops as core
    try:
        core.check_genus("A", 1, "B", 2)
    except core.ObjectProblem as e:
        msg = str(e)
        assert "'A'" in msg and "'B'" in msg and "genus 1" in msg and "genus 2" in msg
    else:
        raise AssertionError("genus mismatch must raise")
    try:
        core.check_genus(None, None, "S", 0)
    except core.ObjectProblem as e:
        assert "genus 0" in str(e) and "'S'" in str(e)
    else:
        raise AssertionError("genus 0 must raise")
    core.check_genus("A", 2, "B", 2)
    core.check_genus(None, None, "B", 3)
