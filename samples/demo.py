"""surfmap demo, run inside Blender (headless):

  blender -b --factory-startup --python-exit-code 1 --python samples/demo.py -- --out DIR

Loads the genus-2 sample pair from samples/meshes (the genus-1 pair when the genus-2 one is
missing; the built-in shapes when no sample is there), runs Surface Map > Show Cut Loops on
both (source = first, target = active), lights the scene, renders with Cycles on the CPU one
PNG per object (loops in pair colours, from the front and from behind) plus one of both, and
saves DIR/demo.blend.
Options (after --): --out DIR (default <repo>/demo_out), --samples N (32), --size WxH (640x480),
--meshes DIR (default samples/meshes).
"""
import math
import os
import sys
import time

import bpy
from mathutils import Vector

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
MESHES = os.path.join(HERE, "meshes")
PAIRS = [  # (genus, source, target)
    (2, "double_torus_g2.obj", "vase_g2.obj"),
    (1, "torus_R1_r0.5.obj", "torus_R1.5_r0.5.obj"),
]


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    opts = {"out": os.path.join(REPO, "demo_out"), "samples": 32, "size": "640x480",
            "meshes": MESHES}
    i = 0
    while i < len(argv):
        key = argv[i].lstrip("-")
        if key not in opts or i + 1 >= len(argv):
            raise SystemExit(f"demo.py: unknown or incomplete option {argv[i]!r} "
                             f"(use --out DIR, --samples N, --size WxH, --meshes DIR)")
        opts[key] = argv[i + 1]
        i += 2
    w, h = (int(x) for x in str(opts["size"]).lower().split("x"))
    return os.path.abspath(opts["out"]), int(opts["samples"]), (w, h), opts["meshes"]


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


def load_pair(sm, meshes):
    for genus, a, b in PAIRS:
        pa, pb = os.path.join(meshes, a), os.path.join(meshes, b)
        if os.path.exists(pa) and os.path.exists(pb):
            print(f"demo: genus-{genus} pair {a} -> {b}")
            # The native module reads OBJ/OFF/PLY through OpenMesh.
            (Va, Pa), (Vb, Pb) = sm.read_polygon_soup(pa), sm.read_polygon_soup(pb)
            return (make_object(os.path.splitext(a)[0], Va.tolist(), Pa),
                    make_object(os.path.splitext(b)[0], Vb.tolist(), Pb))
    print("demo: no sample pair in samples/meshes; using the built-in shapes")
    shapes = getattr(sm, "shapes", None)
    if shapes is not None and hasattr(shapes, "n_hole_torus") and hasattr(shapes, "vase"):
        (Va, Fa), (Vb, Fb) = shapes.n_hole_torus(2), shapes.vase()
        return (make_object("double_torus", Va.tolist(), Fa.tolist()),
                make_object("vase", Vb.tolist(), Fb.tolist()))
    # Blender's own (quad) tori
    objs = []
    for name, R in (("torus_R1", 1.0), ("torus_R1.5", 1.5)):
        bpy.ops.mesh.primitive_torus_add(major_segments=64, minor_segments=32,
                                         major_radius=R, minor_radius=0.5)
        ob = bpy.context.active_object
        ob.name = ob.data.name = name
        for p in ob.data.polygons:
            p.use_smooth = True
        objs.append(ob)
    return tuple(objs)


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
    for ob in objs:
        step = max(1, len(ob.data.vertices) // 4000)
        verts = ob.data.vertices
        pts += [ob.matrix_world @ verts[i].co for i in range(0, len(verts), step)]
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


def show_only(objs):
    keep = set(objs)
    for ob in bpy.data.objects:
        if ob.type in {'MESH', 'CURVE'}:
            ob.hide_render = ob not in keep and ob.parent not in keep


def main():
    out, samples, size, meshes = parse_args()
    os.makedirs(out, exist_ok=True)
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    sm = enable_addon()
    source, target = load_pair(sm, meshes)
    mat = surface_material()
    for ob in (source, target):
        normalise(ob)
        ob.data.materials.append(mat)
    source.location.x -= 1.3
    target.location.x += 1.3
    bpy.context.view_layer.update()

    bpy.context.scene.surfmap.loop_bevel = 0.0045
    for ob in bpy.context.view_layer.objects:
        ob.select_set(ob in (source, target))
    bpy.context.view_layer.objects.active = target
    result = bpy.ops.surfmap.show_cut_loops()
    if result != {'FINISHED'}:
        raise SystemExit(f"demo.py: show_cut_loops returned {result}")
    print("demo:", bpy.context.scene.surfmap.status)

    cam = setup_scene(samples, size)
    written = []
    for ob in (source, target):
        show_only([ob])
        for view, direction in (("front", (0.55, -1.0, 0.75)), ("back", (-0.55, 1.0, 0.75))):
            aim(cam, [ob], direction)
            path = os.path.join(out, f"{ob.name}_loops_{view}.png")
            render(path)
            written.append(path)
    show_only([source, target])
    aim(cam, [source, target], (0.15, -1.0, 0.55))
    path = os.path.join(out, "pair_loops.png")
    render(path)
    written.append(path)
    show_only([source, target])
    blend = os.path.join(out, "demo.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    written.append(blend)
    print("demo: wrote", ", ".join(os.path.basename(p) for p in written))


main()
