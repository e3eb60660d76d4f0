"""An open head and an open mask in Blender (issue 16's check; docs/open_surfaces.md, "In Blender:
an open head and a mask"): the head's UVs transferred onto the mask by Compute Map and, side by
side, by Blender's own Data Transfer modifier on the same pair; the flipped transferred UV
triangles of both counted; in a window, screenshots (a manual check, not a test: the test is
blender_tests/test_open_surfaces.py test_open_head_and_mask_uvs_without_flips).

  blender -b --factory-startup --python scripts/open_pair_check.py -- [--head FILE] [--out DIR]
  Xvfb :99 -screen 0 1600x1200x24 &   DISPLAY=:99 twm -f RC &   (scripts/ui_check.py: RC, why)
  DISPLAY=:99 SURFMAP_PYTHONPATH=build/python blender --factory-startup \\
      --window-geometry 0 0 1600 1200 /tmp/empty.blend --python scripts/open_pair_check.py -- --out DIR

Head: --head FILE (an open mesh of genus 0 with one boundary loop, e.g. a face scan, read in its
file's frame with y up and turned z up, facing -y), else blender_tests/helpers.open_head(). Mask:
helpers.open_mask() fitted into the head's front (its box: the head's width and height, over the
front half of its depth), so that Data Transfer, which projects onto the nearest surface, has a
fair chance. The head gets box-projected UVs (helpers.box_uvs: islands per axis, none flipped),
the layer 'Box'. Three objects: the head, the mask with Compute Map's 'surfmap Box', a copy of the
mask with Data Transfer's (modifier kept live: object 'Mask (Data Transfer)', loop mapping
--mapping, default 'POLYINTERP_NEAREST' "Nearest Face Interpolated"; `--mapping all` counts every
loop mapping). A colour grid shows the UVs; the counts are printed as lines starting with
'OPEN-CHECK' and written beside each object as text.

Flipped: a transferred UV triangle whose signed area (uv_transfer.signed_uv_areas) is <= 0, the
source's own box UVs having none; straddling: uv_transfer.seam_straddling (a triangle whose corners
take UVs from different islands of the head). Ears (mask triangles with all three corners on its
boundary) are counted apart.
"""
import os
import subprocess
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "addon"))
sys.path.insert(0, os.path.join(REPO, "blender_tests"))
argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []


def arg(name, default=""):
    return argv[argv.index(name) + 1] if name in argv else default


OUT = arg("--out", "/tmp/surfmap_open_check")
HEAD = arg("--head")
MAPPING = arg("--mapping", "POLYINTERP_NEAREST")
MASK_SUBDIVISIONS = int(arg("--mask-subdivisions", "5"))
WINDOW = not bpy.app.background


def log(*a):
    print("OPEN-CHECK", *a)
    sys.stdout.flush()


def head_mesh(sm):
    import helpers
    if not HEAD:
        return "Head", *helpers.open_head(5)
    V, polys = sm.read_polygon_soup(HEAD)
    V = np.asarray(V, dtype=float)
    it = sm.intake(V, [list(p) for p in polys], allow_boundary=True)
    V, F = np.asarray(it["V"], dtype=float), np.asarray(it["F"], dtype=np.int64)
    V = np.stack([V[:, 0], -V[:, 2], V[:, 1]], axis=1)      # y up -> z up, facing -y
    return os.path.splitext(os.path.basename(HEAD))[0], V, F


def fitted_mask(V):
    """helpers.open_mask scaled into the head's front: the open_head frame (x in [-0.78, 0.78],
    front at y = -1.2, z in [-0.82, 1.1]) mapped onto the head's box."""
    import helpers
    lo, hi = V.min(axis=0), V.max(axis=0)
    size = np.array([(hi[0] - lo[0]) / 1.56, (hi[1] - lo[1]) / 2.12, (hi[2] - lo[2]) / 1.92])
    if HEAD:   # a face scan is the front alone: its depth is the front half of a head's
        size[1] = (hi[1] - lo[1]) / 1.2
    centre = np.array([0.5 * (lo[0] + hi[0]), lo[1] + 1.2 * size[1], lo[2] + 0.82 * size[2]])
    return helpers.open_mask(MASK_SUBDIVISIONS, centre=centre, size=size)


def count(ob, layer, src, src_layer):
    """(flipped, straddling, ears among the flipped, triangles) of ob's UV layer `layer`,
    transferred from src's `src_layer` (read from the evaluated mesh: Data Transfer's modifier)."""
    import helpers
    from surface_map import uv_transfer as M
    dg = bpy.context.evaluated_depsgraph_get()
    me = ob.evaluated_get(dg).to_mesh()
    me.calc_loop_triangles()
    m = len(me.loop_triangles)
    F = np.empty(3 * m, dtype=np.int64)
    L = np.empty(3 * m, dtype=np.int64)
    me.loop_triangles.foreach_get("vertices", F)
    me.loop_triangles.foreach_get("loops", L)
    F, L = F.reshape(m, 3), L.reshape(m, 3)
    uv = np.empty(2 * len(me.loops))
    me.uv_layers[layer].data.foreach_get("uv", uv)
    uv = uv.reshape(-1, 2)[L]
    ob.evaluated_get(dg).to_mesh_clear()
    A = M.signed_uv_areas(uv)
    flipped = A <= 0
    edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    e, n = np.unique(edges, axis=0, return_counts=True)
    on_b = np.zeros(len(ob.data.vertices), dtype=bool)
    on_b[e[n == 1].ravel()] = True
    ears = np.all(on_b[F], axis=1)
    # Straddling: the preimages of the corners, as Compute Map stores them on the mask
    # (surfmap_map_face / _bary), are the same for both transfers: the question is only
    # which UVs each gives the triangle.
    Fs, Ls = helpers.triangles_of(src)
    Vs = helpers.coords(src)
    suv = helpers.loop_uv_array(src, src_layer)[Ls]
    mask = bpy.data.objects["Mask"]
    face = np.empty(len(mask.data.vertices), dtype=np.int32)
    mask.data.attributes["surfmap_map_face"].data.foreach_get("value", face)
    bary = np.empty(len(mask.data.vertices) * 3, dtype=np.float32)
    mask.data.attributes["surfmap_map_bary"].data.foreach_get("vector", bary)
    pre = M.points_at(Vs, Fs, face, bary.reshape(-1, 3).astype(float))[F]
    straddling = M.seam_straddling(uv, pre, suv, Vs[Fs])
    if os.environ.get("OPEN_CHECK_DEBUG"):
        log("flipped areas", A[flipped], "ears", ears[flipped])
    return int(flipped.sum()), int(straddling), int((flipped & ears).sum()), m


def label(text, location, size):
    cu = bpy.data.curves.new(text[:20], 'FONT')
    cu.align_y = 'TOP'
    cu.body = text
    cu.size = size
    cu.align_x = 'CENTER'
    ob = bpy.data.objects.new("label " + text[:20], cu)
    ob.location = location
    ob.rotation_euler.x = np.pi / 2
    bpy.context.scene.collection.objects.link(ob)
    return ob


def grid_material(layer):
    """A colour grid through the UV layer `layer` (shown in the solid view's Texture colour)."""
    img = bpy.data.images.get("grid") or bpy.data.images.new("grid", 1024, 1024)
    img.generated_type = 'COLOR_GRID'
    mat = bpy.data.materials.new(f"grid {layer}")
    mat.use_nodes = True
    nt = mat.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    uvn = nt.nodes.new("ShaderNodeUVMap")
    uvn.uv_map = layer
    nt.links.new(uvn.outputs["UV"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    nt.nodes.active = tex
    return mat


def setup():
    import addon_utils
    import helpers
    addon_utils.enable("surface_map", default_set=True, handle_error=None)
    sm = helpers.sm()
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    name, V, F = head_mesh(sm)
    Vm, Fm = fitted_mask(V)
    width = float(np.ptp(V[:, 0]))
    gap = 1.6 * width
    head = helpers.mesh_object(name, V, F, (-gap, 0, 0))
    mask = helpers.mesh_object("Mask", Vm, Fm, (0, 0, 0))
    for ob in (head, mask):
        ob.data.polygons.foreach_set("use_smooth", [True] * len(ob.data.polygons))
    helpers.set_loop_uvs(head, "Box", helpers.box_uvs(head))
    for ob in (head, mask):
        info = sm.intake(helpers.coords(ob), helpers.triangles_of(ob)[0], allow_boundary=True)
        log(f"'{ob.name}': {len(ob.data.vertices)} vertices, {len(ob.data.polygons)} faces, genus "
            f"{info['info']['genus']}, {len(info['boundary_loops'])} boundary loop(s)")
    bpy.ops.object.select_all(action='DESELECT')
    head.select_set(True)
    mask.select_set(True)
    bpy.context.view_layer.objects.active = mask
    bpy.context.scene.surfmap.loop_bevel = 0.012     # the boundary curves thick enough to see
    t = time.time()
    res = bpy.ops.surfmap.compute_map()
    log(f"Compute Map {res} in {time.time() - t:.1f}s: {bpy.context.scene.surfmap.map_status}")
    ours = count(mask, "surfmap Box", head, "Box")
    log(f"Compute Map's UVs on the mask: {ours[0]} flipped ({ours[2]} of them ears), {ours[1]} "
        f"straddling, of {ours[3]} triangles")
    # Data Transfer on a copy of the mask, the objects' own coordinates (side by side here).
    dt = mask.copy()
    dt.data = mask.data.copy()
    dt.name = "Mask (Data Transfer)"
    for key in list(dt.data.uv_layers):
        if key.name != "surfmap Box":
            dt.data.uv_layers.remove(key)
    dt.data.uv_layers["surfmap Box"].name = "Box"
    if dt.data.shape_keys:
        dt.shape_key_clear()
    bpy.context.scene.collection.objects.link(dt)
    dt.location.x = gap
    mod = dt.modifiers.new("DataTransfer", 'DATA_TRANSFER')
    mod.object = head
    mod.use_object_transform = False
    mod.use_loop_data = True
    mod.data_types_loops = {'UV'}
    mod.layers_uv_select_src = 'ALL'
    mod.layers_uv_select_dst = 'NAME'
    theirs = {}
    mappings = ([MAPPING] if MAPPING != "all" else
                [i.identifier for i in mod.bl_rna.properties["loop_mapping"].enum_items])
    for mapping in mappings:
        mod.loop_mapping = mapping
        dt.data.update()
        theirs[mapping] = count(dt, "Box", head, "Box")
        c = theirs[mapping]
        log(f"Data Transfer ({mapping}) UVs on the mask: {c[0]} flipped ({c[2]} of them ears), "
            f"{c[1]} straddling, of {c[3]} triangles")
    mod.loop_mapping = mappings[0]
    c = theirs[mappings[0]]
    for ob, layer in ((head, "Box"), (mask, "surfmap Box"), (dt, "Box")):
        ob.data.uv_layers.active = ob.data.uv_layers[layer]
        ob.data.materials.clear()
        ob.data.materials.append(grid_material(layer))
    z = float(min(V[:, 2].min(), Vm[:, 2].min())) - 0.1 * width
    size = 0.09 * width
    label(f"{name[:24]}\nUVs 'Box'", (-gap, 0, z), size)
    label(f"Compute Map\n{ours[0]} flipped, {ours[1]} straddling", (0, 0, z), size)
    label(f"Data Transfer\n{c[0]} flipped, {c[1]} straddling", (gap, 0, z), size)
    return head, mask, dt


def view3d():
    win = bpy.context.window_manager.windows[0]
    for area in win.screen.areas:
        if area.type == 'VIEW_3D':
            return win, area, next(r for r in area.regions if r.type == 'WINDOW')
    raise RuntimeError("no 3D view")


def call(op, **kw):
    win, area, region = view3d()
    with bpy.context.temp_override(window=win, area=area, region=region):
        return op(**kw)


def xdo(*a):
    subprocess.run(["xdotool", *a], check=False)


def shot(name):
    path = os.path.join(OUT, name)
    subprocess.run(["import", "-window", "root", path], check=False)
    log("screenshot", path)


STEPS = []


def step():
    if not STEPS:
        bpy.ops.wm.quit_blender()
        return None
    wait = STEPS.pop(0)()
    return wait if wait is not None else 2.0


def window_steps(head, mask, dt):
    def arrange():
        win, area, region = view3d()
        space = area.spaces.active
        space.show_region_ui = True
        space.overlay.show_floor = False
        space.overlay.show_axis_x = space.overlay.show_axis_y = False
        space.shading.type = 'SOLID'
        space.shading.color_type = 'TEXTURE'
        ui = next(r for r in area.regions if r.type == 'UI')
        log("sidebar width px", ui.width, "window", win.width, win.height)
        # The sidebar's 'Surface Map' tab (no Python API in 3.4): the last tab at its right edge.
        ids = subprocess.run(["xdotool", "search", "--name", "Blender"], capture_output=True,
                             text=True).stdout.split()
        for wid in ids:
            xdo("windowfocus", wid)
        x, y_top = ui.x + ui.width - 10, win.height - (ui.y + ui.height)
        xdo("mousemove", str(x), str(y_top + 195))
        time.sleep(0.3)
        xdo("mousemove", str(x + 1), str(y_top + 196))
        time.sleep(0.3)
        for _ in range(2):   # the first click can go to focusing the window
            xdo("mousedown", "1")
            time.sleep(0.15)
            xdo("mouseup", "1")
            time.sleep(0.5)
        for ob in bpy.data.objects:
            ob.select_set(ob.type == 'MESH' or ob.name.startswith("label"))
        call(bpy.ops.view3d.view_axis, type='FRONT')
        call(bpy.ops.view3d.view_selected)
        for ob in bpy.data.objects:
            ob.select_set(ob in (head, mask))
        bpy.context.view_layer.objects.active = mask
        return 8.0

    def front():
        shot("open_head_mask_front.png")
        call(bpy.ops.view3d.view_orbit, angle=0.6, type='ORBITRIGHT')
        return 6.0

    def turned():
        shot("open_head_mask_turned.png")
        # The boundary curves with the meshes in plain solid, drawn again by the Cut Loops panel's
        # Show Cut Loops (an open mesh: its boundary, like the cut loops), nothing selected.
        win, area, region = view3d()
        area.spaces.active.shading.color_type = 'MATERIAL'
        for ob in bpy.data.objects:
            ob.select_set(ob in (head, mask))
        bpy.context.view_layer.objects.active = mask
        call(bpy.ops.surfmap.show_cut_loops)
        log("Show Cut Loops:", bpy.context.scene.surfmap.status)
        for ob in bpy.data.objects:
            ob.select_set(False)
        call(bpy.ops.view3d.view_axis, type='FRONT')
        return 6.0

    def loops():
        shot("open_head_mask_boundary.png")
        return 1.0

    STEPS.extend([arrange, front, turned, loops])
    bpy.app.timers.register(step, first_interval=4.0)


os.makedirs(OUT, exist_ok=True)
objs = setup()
if WINDOW:
    window_steps(*objs)
