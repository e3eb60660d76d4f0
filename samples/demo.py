"""surfmap demo, run inside Blender (headless):

  blender -b --factory-startup --python-exit-code 1 --python samples/demo.py -- --out DIR

For the genus-2 sample pair (double torus -> vase) and the genus-1 pair of tori (paper
Fig. 9c) from samples/meshes: Surface Map > Show Cut Loops on both, the source unwrapped along
its cut loops (one UV island; the torus gets the classic (u, v) layout instead, on which the
checker tiles across the seams) and given a checker texture, then Surface Map > Compute Map, which
writes the transferred UVs, the morph shape keys, the distortion colours and the stored
correspondence. Renders with Cycles on the CPU (denoising off), per pair:
  <pair>_loops.png             both objects with their cut loops
  <pair>_source_checker.png    the source with the checker on its own UVs
  <pair>_target_transferred.png the target with the checker on the transferred UVs
  <pair>_target_datatransfer.png for comparison: Blender's Data Transfer (nearest face
                               interpolated UVs) of the same checker, with its defect counts
  <pair>_morph50.png           the source at 50% of its morph shape key (checker kept)
  <pair>_refined_morph100.png  the refined morph object (paper §VII-E) at 100%: the source's
                               checker on the target's shape
  <pair>_distortion_before.png the dilatation D' of the initial map (when the core measures
                               it for that genus), on the same colour scale as
  <pair>_distortion_after.png  the D' of the optimised map
  g2_landmark_free.png         close-up of the target's checker around a target vertex (red) ...
  g2_landmark_far.png          ... and the same view of a second map (copies of the genus-2 pair)
                               with one landmark held on that vertex, 5 edges from where the map
                               puts it: the checker through that map, and how it was held
plus the texture bake's images and the morph GIF (samples/demo_bake.py lists them),
and saves DIR/demo.blend with every object and output. Options (after --): --out DIR
(default <repo>/demo_out), --samples N (16), --size WxH (640x480), --meshes DIR
(default samples/meshes), --pairs g2,g1.
"""
import math
import os
import sys
import time

import bpy
import numpy as np
from mathutils import Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import types  # noqa: E402
import demo_bake  # noqa: E402  (samples/demo_bake.py: the texture bake and the morph GIF)

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
MESHES = os.path.join(HERE, "meshes")
PAIRS = {  # tag: (genus, source, target)
    "g2": (2, "double_torus_g2.obj", "vase_g2.obj"),
    "g1": (1, "torus_R1_r0.5.obj", "torus_R1.5_r0.5.obj"),
}


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    opts = {"out": os.path.join(REPO, "demo_out"), "samples": 16, "size": "640x480",
            "meshes": MESHES, "pairs": "g2,g1"}
    i = 0
    while i < len(argv):
        key = argv[i].lstrip("-")
        if key not in opts or i + 1 >= len(argv):
            raise SystemExit(f"demo.py: unknown or incomplete option {argv[i]!r} "
                             f"(use --out DIR, --samples N, --size WxH, --meshes DIR, "
                             f"--pairs g2,g1)")
        opts[key] = argv[i + 1]
        i += 2
    w, h = (int(x) for x in str(opts["size"]).lower().split("x"))
    return (os.path.abspath(opts["out"]), int(opts["samples"]), (w, h), opts["meshes"],
            [t for t in opts["pairs"].split(",") if t])


def enable_addon():
    import addon_utils
    sys.path.insert(0, os.path.join(REPO, "addon"))
    if addon_utils.enable("surface_map", default_set=True, handle_error=None) is None:
        raise SystemExit("demo.py: could not enable the surface_map add-on")
    from surface_map import native
    mod = native.load()
    if mod is None:
        raise SystemExit("demo.py: the surfmap native module is missing: " + native.error())
    return mod


def make_object(name, V, polys):
    me = bpy.data.meshes.new(name)
    me.from_pydata(V, [], polys)
    me.update()
    for p in me.polygons:
        p.use_smooth = True
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def load_pair(sm, meshes, tag):
    genus, a, b = PAIRS[tag]
    pa, pb = os.path.join(meshes, a), os.path.join(meshes, b)
    if not (os.path.exists(pa) and os.path.exists(pb)):
        raise SystemExit(f"demo.py: the sample pair {a}, {b} is missing from {meshes} "
                         f"(samples/generate.py writes it)")
    print(f"demo: genus-{genus} pair {a} -> {b}")
    # The native module reads OBJ/OFF/PLY through OpenMesh.
    (Va, Pa), (Vb, Pb) = sm.read_polygon_soup(pa), sm.read_polygon_soup(pb)
    return (make_object(os.path.splitext(a)[0], Va.tolist(), Pa),
            make_object(os.path.splitext(b)[0], Vb.tolist(), Pb))


def normalise(ob, size=2.0):
    """Scales and centres the object (object transform only) so both fit the same frame."""
    bb = [Vector(c) for c in ob.bound_box]
    lo = Vector((min(c.x for c in bb), min(c.y for c in bb), min(c.z for c in bb)))
    hi = Vector((max(c.x for c in bb), max(c.y for c in bb), max(c.z for c in bb)))
    s = size / max((hi - lo).length, 1e-12)
    ob.scale = (s, s, s)
    ob.location = -(lo + hi) / 2 * s


def surface_material():
    mat = bpy.data.materials.new("SurfMap surface")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.36, 0.37, 0.40, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.5
    mat.diffuse_color = (0.36, 0.37, 0.40, 1.0)
    return mat


def world_bounds(objs):
    pts = [ob.matrix_world @ Vector(c) for ob in objs for c in ob.bound_box]
    lo = Vector((min(p.x for p in pts), min(p.y for p in pts), min(p.z for p in pts)))
    hi = Vector((max(p.x for p in pts), max(p.y for p in pts), max(p.z for p in pts)))
    return lo, hi


def setup_scene(samples, size):
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 4
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = 'PNG'
    scene.render.film_transparent = False
    scene.view_settings.view_transform = 'Standard'
    world = bpy.data.worlds.new("SurfMap world") if scene.world is None else scene.world
    scene.world = world
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.18, 0.19, 0.21, 1.0)
    bg.inputs["Strength"].default_value = 0.6
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.lens = 50
    scene.collection.objects.link(cam)
    scene.camera = cam
    for name, rot, energy in (("Key", (math.radians(50), 0, math.radians(30)), 2.6),
                              ("Fill", (math.radians(60), 0, math.radians(-140)), 0.9),
                              ("Top", (0, 0, 0), 0.6)):
        light = bpy.data.objects.new(name, bpy.data.lights.new(name, 'SUN'))
        light.data.energy = energy
        light.data.angle = math.radians(8)
        light.rotation_euler = rot
        scene.collection.objects.link(light)
    return cam


def aim(cam, objs, direction):
    """Places the camera along `direction` from the objects' centre so that they fill the
    frame (bounding sphere inside the narrower field of view)."""
    from bpy_extras.object_utils import world_to_camera_view
    scene = bpy.context.scene
    lo, hi = world_bounds(objs)
    centre = (lo + hi) / 2
    radius = (hi - lo).length / 2
    pts = []
    depsgraph = bpy.context.evaluated_depsgraph_get()
    for ob in objs:
        verts = ob.evaluated_get(depsgraph).data.vertices  # with shape keys and modifiers
        step = max(1, len(verts) // 4000)
        pts += [ob.matrix_world @ verts[i].co for i in range(0, len(verts), step)]
    if pts:
        lo = Vector((min(p.x for p in pts), min(p.y for p in pts), min(p.z for p in pts)))
        hi = Vector((max(p.x for p in pts), max(p.y for p in pts), max(p.z for p in pts)))
        centre, radius = (lo + hi) / 2, (hi - lo).length / 2
    d = Vector(direction).normalized()
    cam.rotation_euler = (-d).to_track_quat('-Z', 'Y').to_euler()
    dist = radius * 4
    for _ in range(4):  # the frame scales about 1/distance: a few fixed-point steps
        cam.location = centre + d * dist
        bpy.context.view_layer.update()
        ndc = [world_to_camera_view(scene, cam, p) for p in pts]
        ext = max(max(abs(c.x - 0.5), abs(c.y - 0.5)) for c in ndc) * 2  # 1.0 = frame edge
        dist *= ext / 0.86
    cam.location = centre + d * dist
    cam.data.clip_start = dist / 100
    cam.data.clip_end = dist * 10


def render(path):
    bpy.context.scene.render.filepath = path
    t = time.time()
    bpy.ops.render.render(write_still=True)
    print(f"demo: rendered {path} in {time.time() - t:.1f}s")


def show_only(objs, curves=False):
    keep = set(objs)
    for ob in bpy.data.objects:
        if ob.type == 'MESH':
            ob.hide_render = ob not in keep
        elif ob.type == 'CURVE':
            ob.hide_render = not (curves and ob.parent in keep)


def checker_material(name, uv_map):
    """Checker on the named UV map (two warm/cool tones, demo_bake.CHECKER_*: the image the
    bake reads has the same pattern)."""
    mat, chk = demo_bake.uv_texture_material(name, uv_map, "ShaderNodeTexChecker")
    chk.inputs["Scale"].default_value = demo_bake.CHECKER_SCALE
    chk.inputs["Color1"].default_value = demo_bake.CHECKER_COLOURS[0]
    chk.inputs["Color2"].default_value = demo_bake.CHECKER_COLOURS[1]
    return mat


def attribute_material(name, attribute):
    """Shows a colour attribute as it is (emission plus a little shading for the shape)."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    col = nt.nodes.new("ShaderNodeVertexColor")
    col.layer_name = attribute
    nt.links.new(col.outputs["Color"], bsdf.inputs["Base Color"])
    if "Emission" in bsdf.inputs:
        nt.links.new(col.outputs["Color"], bsdf.inputs["Emission"])
    if "Emission Strength" in bsdf.inputs:
        bsdf.inputs["Emission Strength"].default_value = 0.5
    bsdf.inputs["Roughness"].default_value = 0.6
    return mat


def set_material(ob, mat):
    ob.data.materials.clear()
    ob.data.materials.append(mat)


def select_pair(source, target):
    for ob in bpy.context.view_layer.objects:
        ob.select_set(ob in (source, target))
    bpy.context.view_layer.objects.active = target


def unwrap_along_seams(ob):
    """UV-unwraps ob (angle based) along its marked seams: the cut loops give one island."""
    for o in bpy.context.view_layer.objects:
        o.select_set(o == ob)
    bpy.context.view_layer.objects.active = ob
    if not ob.data.uv_layers:
        ob.data.uv_layers.new(name="UVMap")
    bpy.ops.object.mode_set(mode='EDIT')
    bpy.ops.mesh.select_all(action='SELECT')
    bpy.ops.uv.unwrap(method='ANGLE_BASED', margin=0.02)
    bpy.ops.object.mode_set(mode='OBJECT')


VIEW = (0.55, -1.0, 0.75)


def torus_uvs(ob, R):
    """UV map 'UVMap' of a torus of revolution around z (major radius R, local coordinates):
    u along the ring, v around the tube, each in [0, 1) with the seams at 0 (per polygon
    unwrapped, so polygons across the seams get UVs just past 1)."""
    me = ob.data
    layer = me.uv_layers.get("UVMap") or me.uv_layers.new(name="UVMap")
    me.uv_layers.active = layer
    co = np.empty(len(me.vertices) * 3)
    me.vertices.foreach_get("co", co)
    lv = np.empty(len(me.loops), dtype=np.int64)
    me.loops.foreach_get("vertex_index", lv)
    P = co.reshape(-1, 3)[lv]
    u = np.arctan2(P[:, 1], P[:, 0]) / (2 * np.pi) % 1.0
    v = np.arctan2(P[:, 2], np.hypot(P[:, 0], P[:, 1]) - R) / (2 * np.pi) % 1.0
    start = np.empty(len(me.polygons), dtype=np.int64)
    me.polygons.foreach_get("loop_start", start)
    total = np.empty(len(me.polygons), dtype=np.int64)
    me.polygons.foreach_get("loop_total", total)
    poly = np.repeat(np.arange(len(start)), total)
    for a in (u, v):
        mx = np.zeros(len(start))
        np.maximum.at(mx, poly, a)
        a[:] = np.where(mx[poly] - a > 0.5, a + 1.0, a)
    layer.data.foreach_set("uv", np.stack([u, v], axis=1).astype(np.float32).ravel())


def emission_material(name, colour):
    """The named material (made once) emitting `colour` only: unlit text and plates."""
    mat = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    for n in list(nodes):
        nodes.remove(n)
    em = nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = colour
    outn = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(em.outputs["Emission"], outn.inputs["Surface"])
    return mat


def caption(cam, text):
    """A line of white text at the bottom of the camera's view (parented to the camera)."""
    cu = bpy.data.curves.new("caption", 'FONT')
    cu.body = text
    cu.align_x = 'CENTER'
    # Just beyond the near clip plane (scaled with its depth, so it looks the same): nothing
    # comes in front of it however close the camera is.
    depth = 2.0 * cam.data.clip_start
    cu.size = 0.017 * depth
    ob = bpy.data.objects.new("caption", cu)
    bpy.context.scene.collection.objects.link(ob)
    cu.materials.append(emission_material("SurfMap caption", (1, 1, 1, 1)))
    ob.parent = cam
    ob.location = (0.0, -0.245 * depth, -depth)   # camera space, near the bottom edge
    ob.hide_render = False
    # A dark plate behind the text (its child): readable over a bright object too.
    bpy.context.view_layer.update()
    w, h = ob.dimensions.x, cu.size
    pm = bpy.data.meshes.new("caption plate")
    pm.from_pydata([(-0.52 * w, -0.35 * h, 0), (0.52 * w, -0.35 * h, 0), (0.52 * w, 1.0 * h, 0),
                    (-0.52 * w, 1.0 * h, 0)], [], [(0, 1, 2, 3)])
    plate = bpy.data.objects.new("caption plate", pm)
    bpy.context.scene.collection.objects.link(plate)
    pm.materials.append(emission_material("SurfMap caption plate", (0.05, 0.05, 0.06, 1)))
    plate.parent = ob
    plate.location = (0.0, 0.0, -0.002 * depth)
    plate.hide_render = False
    for o in (ob, plate):     # no shadows of the caption onto the scene
        if hasattr(o, "visible_shadow"):
            o.visible_shadow = False
    return ob


def compare_with_data_transfer(source, target, uv_name, shot, cam):
    """For comparison: Blender's own Data Transfer (face corner UVs, nearest face interpolated)
    onto a copy of the target placed on top of the source, rendered like ours."""
    from surface_map import uv_transfer
    copy = bpy.data.objects.new(f"{target.name} (Data Transfer)", target.data.copy())
    bpy.context.scene.collection.objects.link(copy)
    copy.matrix_world = source.matrix_world.copy()    # overlap the source: DT works in space
    copy.scale = target.scale
    copy.location = source.location
    dt_layer = copy.data.uv_layers.new(name=uv_name)   # filled by name from the source's
    mod = copy.modifiers.new("DataTransfer", 'DATA_TRANSFER')
    mod.object = source
    mod.use_loop_data = True
    mod.data_types_loops = {'UV'}
    mod.loop_mapping = 'POLYINTERP_NEAREST'
    mod.layers_uv_select_src = uv_name
    mod.layers_uv_select_dst = 'NAME'
    set_material(copy, checker_material(f"{copy.name} checker", dt_layer.name))
    bpy.context.view_layer.update()
    # the counts of the transfer's defects, ours and Data Transfer's, on the target's triangles
    ev = copy.evaluated_get(bpy.context.evaluated_depsgraph_get())
    me = ev.to_mesh()
    me.calc_loop_triangles()
    m = len(me.loop_triangles)
    L = np.empty(m * 3, dtype=np.int64)
    me.loop_triangles.foreach_get("loops", L)
    Fv = np.empty(m * 3, dtype=np.int64)
    me.loop_triangles.foreach_get("vertices", Fv)
    co = np.empty(len(me.vertices) * 3)
    me.vertices.foreach_get("co", co)
    xyz = co.reshape(-1, 3)[Fv.reshape(-1, 3)]
    counts = {}
    for name in (uv_name, f"surfmap {uv_name}"):
        uv = np.empty(len(me.loops) * 2)
        me.uv_layers[name].data.foreach_get("uv", uv)
        counts[name] = uv_transfer.uv_quality(uv.reshape(-1, 2)[L.reshape(-1, 3)], xyz)
    ev.to_mesh_clear()
    print(f"demo: {m} target triangles; UV triangles flipped / stretched across the layout: "
          f"surfmap {counts[f'surfmap {uv_name}']}, Data Transfer {counts[uv_name]}")
    fl, st = counts[uv_name]
    shot("target_datatransfer", [copy],
         text=f"Blender Data Transfer (nearest face interpolated): {fl} flipped, {st} "
              f"stretched UV triangles")
    copy.hide_render = True
    copy.hide_set(True)
    return counts[f"surfmap {uv_name}"]


def marker(name, location, radius):
    """A small red emissive sphere (landmark targets)."""
    me = bpy.data.meshes.new(name)
    import bmesh
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=16, v_segments=8, radius=radius)
    bm.to_mesh(me)
    bm.free()
    ob = bpy.data.objects.new(name, me)
    ob.location = location
    bpy.context.scene.collection.objects.link(ob)
    mat = bpy.data.materials.new(f"{name} red")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.9, 0.05, 0.03, 1.0)
    if "Emission" in bsdf.inputs:
        bsdf.inputs["Emission"].default_value = (0.9, 0.05, 0.03, 1.0)
    set_material(ob, mat)
    return ob


def landmark_demo(source, target, uv_name, shot, hops=5):
    """Copies of the mapped pair, one landmark: a source vertex held on the target vertex
    `hops` edges (along a shortest path towards the farthest vertex) from where the map
    without landmarks put it; mapped again (plain pins would fold the map there; the core
    walks the landmark there by its barrier continuation) and the target copy rendered with
    the checker through that map, a marker on the landmark's target."""
    from surface_map import blender_io
    import collections
    s_copy = source.copy()
    s_copy.data = source.data.copy()
    t_copy = target.copy()
    t_copy.data = target.data.copy()
    for ob, n in ((s_copy, f"{source.name} (landmark)"), (t_copy, f"{target.name} (landmark)")):
        ob.name = n       # (the copied layers are the add-on's: the new map overwrites them)
        bpy.context.scene.collection.objects.link(ob)
    me_t = target.data
    Vt = np.empty(len(me_t.vertices) * 3)
    me_t.vertices.foreach_get("co", Vt)
    Vt = Vt.reshape(-1, 3)
    sv = len(source.data.vertices) // 3
    face = source.data.attributes[blender_io.CORR_FACE].data[sv].value
    bary = np.array(source.data.attributes[blender_io.CORR_BARY].data[sv].vector)
    me_t.calc_loop_triangles()
    tri = np.empty(len(me_t.loop_triangles) * 3, dtype=np.int64)
    me_t.loop_triangles.foreach_get("vertices", tri)
    tri = tri.reshape(-1, 3)
    image = bary @ Vt[tri[face]]
    t0 = int(np.argmin(((Vt - image) ** 2).sum(1)))
    nb = collections.defaultdict(set)
    for e in me_t.edges:
        a, b = e.vertices
        nb[a].add(b), nb[b].add(a)
    far = int(np.argmax(((Vt - Vt[t0]) ** 2).sum(1)))
    prev, queue = {t0: -1}, collections.deque([t0])
    while queue:
        u = queue.popleft()
        for v in nb[u]:
            if v not in prev:
                prev[v], _ = u, queue.append(v)
    path = [far]
    while prev[path[-1]] != -1:
        path.append(prev[path[-1]])
    tv = path[::-1][min(hops, len(path) - 1)]
    s_copy.vertex_groups.new(name="lm_demo").add([sv], 1.0, 'REPLACE')
    t_copy.vertex_groups.new(name="lm_demo").add([int(tv)], 1.0, 'REPLACE')
    settings = bpy.context.scene.surfmap
    saved = (settings.landmark_mode, settings.write_refined, settings.write_distortion,
             settings.write_morph)
    settings.landmark_mode, settings.write_refined = 'GROUPS', False
    settings.write_distortion = settings.write_morph = False
    select_pair(s_copy, t_copy)
    t = time.time()
    result = bpy.ops.surfmap.compute_map()
    (settings.landmark_mode, settings.write_refined, settings.write_distortion,
     settings.write_morph) = saved
    if result != {'FINISHED'}:
        raise SystemExit(f"demo.py: compute_map with a landmark returned {result}")
    status = settings.landmark_status
    print(f"demo: compute_map with a far landmark in {time.time() - t:.1f}s:", settings.map_status)
    set_material(t_copy, checker_material(f"{t_copy.name} checker", f"surfmap {uv_name}"))
    size = (Vector(t_copy.bound_box[6]) - Vector(t_copy.bound_box[0])).length
    where = t_copy.matrix_world @ Vector(Vt[tv])
    m = marker("landmark target", where, 0.01 * size * t_copy.scale[0])
    # the frame: a (not rendered) sphere around the target vertex, half the object across
    # (nearer, the object would come in front of the caption, 1 unit ahead of the camera)
    frame = marker("landmark frame", where, 0.25 * size * t_copy.scale[0])
    frame.hide_render = True
    normal = (t_copy.matrix_world.to_3x3() @ t_copy.data.vertices[int(tv)].normal).normalized()
    facing = normal + Vector(VIEW).normalized() * 0.3   # looking at the target vertex
    shot("landmark_free", [target, m], direction=tuple(facing), fit=[frame],
         text="the map without landmarks around the landmark's target vertex (red)")
    shot("landmark_far", [t_copy, m], direction=tuple(facing), fit=[frame],
         text=f"{status.split(' (')[0]}, {hops} edges from its free image (red: its target)")
    bpy.data.objects.remove(frame, do_unlink=True)
    for ob in (s_copy, t_copy, m):
        ob.hide_render = True
        ob.hide_set(True)


def demo_pair(sm, meshes, tag, offset_y, cam, out, written):
    t0 = time.time()
    source, target = load_pair(sm, meshes, tag)
    plain = surface_material()
    for ob in (source, target):
        normalise(ob)
        ob.location.y += offset_y
        set_material(ob, plain)
    source.location.x -= 1.3
    target.location.x += 1.3
    bpy.context.view_layer.update()

    # 1. cut loops on both (they become the source's UV seams), one UV island on the source
    bpy.context.scene.surfmap.loop_bevel = 0.0045
    select_pair(source, target)
    result = bpy.ops.surfmap.show_cut_loops()
    if result != {'FINISHED'}:
        raise SystemExit(f"demo.py: show_cut_loops returned {result}")
    print("demo:", bpy.context.scene.surfmap.status)
    if tag == "g1":
        torus_uvs(source, 1.0)   # the classic (u, v) layout: the checker tiles across its seams
    else:
        unwrap_along_seams(source)
    uv_name = source.data.uv_layers.active.name

    # 2. the map and all its outputs
    select_pair(source, target)
    bpy.context.scene.surfmap.write_refined = True
    t = time.time()
    result = bpy.ops.surfmap.compute_map()
    if result != {'FINISHED'}:
        raise SystemExit(f"demo.py: compute_map returned {result}")
    print(f"demo: compute_map in {time.time() - t:.1f}s:", bpy.context.scene.surfmap.map_status)
    cands = bpy.context.scene.surfmap.candidates
    print("demo: handle correspondences (energy):",
          "; ".join(f"{c.index}: {c.energy:.6g}" if c.solved else f"{c.index}: not solved"
                    for c in cands))

    def shot(name, objs, curves=False, direction=VIEW, text=None, fit=None):
        show_only(objs, curves)
        aim(cam, fit or objs, direction)
        label = caption(cam, text) if text else None
        path = os.path.join(out, f"{tag}_{name}.png")
        render(path)
        written.append(path)
        if label is not None:
            for child in list(label.children):
                bpy.data.objects.remove(child, do_unlink=True)
            bpy.data.objects.remove(label, do_unlink=True)

    shot("loops", [source, target], curves=True, direction=(0.15, -1.0, 0.55),
         text=f"cut loops of {source.name} (source) and {target.name} (target)")
    set_material(source, checker_material(f"{source.name} checker", uv_name))
    set_material(target, checker_material(f"{target.name} checker", f"surfmap {uv_name}"))
    shot("source_checker", [source], text=f"source {source.name}: checker on its UV map")
    fl, st = compare_with_data_transfer(source, target, uv_name, shot, cam)
    shot("target_transferred", [target],
         text=f"surfmap: the source's checker through the map: {fl} flipped, {st} stretched "
              f"UV triangles")
    demo_bake.bake_comparison(types.SimpleNamespace(**globals()), source, target, uv_name, shot,
                              out, tag, written)
    key = source.data.shape_keys.key_blocks[f"surfmap to {target.name}"]
    key.value = 0.5
    bpy.context.view_layer.update()
    shot("morph50", [source], text=f"{source.name} at 50% of its morph onto {target.name}")
    key.value = 0.0
    if tag == "g2":
        demo_bake.morph_gif(types.SimpleNamespace(**globals()), source, target.name, cam, out,
                            tag, written)
    refined = bpy.data.objects.get(f"{source.name} refined morph")
    if refined is not None:  # the refined morph at 100%, beside the target it imitates
        set_material(refined, checker_material(f"{refined.name} checker", uv_name))
        refined.data.shape_keys.key_blocks[f"surfmap to {target.name}"].value = 1.0
        bpy.context.view_layer.update()
        n0, n1 = len(source.data.vertices), len(refined.data.vertices)
        shot("refined_morph100", [refined], text=f"refined morph at 100% ({n0} -> {n1} "
                                                 f"vertices): the source's checker in the "
                                                 f"target's shape")
        refined.hide_render = True
    bpy.context.view_layer.update()
    for which, attr in (("before", "surfmap dilatation initial"), ("after", "surfmap dilatation")):
        if source.data.color_attributes.get(attr) is None:
            print(f"demo: no {attr!r} (the core does not measure the initial map's per-face "
                  f"D' for genus {source.data['surfmap_map']['genus']}); skipping {which}")
            continue
        set_material(source, attribute_material(f"{source.name} {attr}", attr))
        lo, hi = bpy.context.scene.surfmap.dilatation_range
        shot(f"distortion_{which}", [source],
             text=f"{'initial' if which == 'before' else 'optimised'} map: dilatation D' "
                  f"{lo:.2f} (violet) to {hi:.2f} (yellow)")
    set_material(source, checker_material(f"{source.name} checker", uv_name))
    if tag == "g2":
        landmark_demo(source, target, uv_name, shot)
    print(f"demo: pair {tag} done in {time.time() - t0:.1f}s")
    return source, target


def main():
    out, samples, size, meshes, tags = parse_args()
    os.makedirs(out, exist_ok=True)
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    sm = enable_addon()
    cam = setup_scene(samples, size)
    written = []
    objs = []
    for i, tag in enumerate(tags):
        objs += demo_pair(sm, meshes, tag, 6.0 * i, cam, out, written)
    show_only(objs, curves=True)
    blend = os.path.join(out, "demo.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    written.append(blend)
    print("demo: wrote", ", ".join(os.path.basename(p) for p in written))


if __name__ == "__main__":  # samples/domain_demo.py imports this file
    main()
