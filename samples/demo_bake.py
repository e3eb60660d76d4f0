"""The demo's texture-bake part (imported by samples/demo.py, inside Blender): the source's
checker as an IMAGE texture baked onto the target three ways, and the morph as an animation.

  <pair>_source_image.png            the source with the checker image on its UV map
  <pair>_target_baked.png            Surface Map > Bake Textures: the checker baked through the
                                     map into the target's own (Smart UV Project) layout
  <pair>_target_selected_to_active.png  Blender's own Cycles bake, Selected to Active (rays cast
                                     from the target, placed over the source, along its normals;
                                     the same rays through mathutils.bvhtree when Cycles bakes
                                     black, as Debian's Blender 3.4.1 does here)
  <pair>_bake_comparison.png         Data Transfer | transferred UVs | Bake Textures | Selected
                                     to Active side by side (PIL)
  <pair>_seam_transferred.png, <pair>_seam_baked.png, <pair>_bake_seams.png (both): a close-up
                                     of a source seam's image on the target, transferred UVs
                                     (saw-teeth) against the bake
  <pair>_morph.gif                   the source's morph shape key animated 0 -> 1 -> 0 (keyed
                                     on frames 0..N-1 in demo.blend), rendered frames as a GIF
"""
import math
import os
import time

import bpy
import numpy as np

# Blender's Checker Texture node as the demo's checker_material sets it up (Scale 16, colours
# in scene-linear): fac = 1 (Color1) where floor(16 u) and floor(16 v) differ in parity.
CHECKER_SCALE = 16.0
CHECKER_COLOURS = ((0.85, 0.55, 0.12, 1.0), (0.08, 0.25, 0.55, 1.0))


def checker_image(name, size=1024):
    """A float (scene-linear) image of the demo's checker: the same pattern as the procedural
    one on the same UVs, now as pixels a bake can read."""
    c = (np.arange(size) + 0.5) / size * CHECKER_SCALE
    xi = np.floor(c).astype(np.int64) % 2
    odd = xi[None, :] != xi[:, None]                 # rows = v, columns = u
    px = np.where(odd[..., None], CHECKER_COLOURS[0], CHECKER_COLOURS[1]).astype(np.float32)
    img = bpy.data.images.get(name) or bpy.data.images.new(name, size, size, alpha=True,
                                                           float_buffer=True)
    img.pixels.foreach_set(px.ravel())
    img.pack()
    return img


def uv_texture_material(name, uv_map, texture_node):
    """A new material whose Base Color is a texture node of type `texture_node` read on the
    named UV map (roughness 0.55): (material, texture node); the demo's checker and image
    materials."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    uv = nt.nodes.new("ShaderNodeUVMap")
    uv.uv_map = uv_map
    tex = nt.nodes.new(texture_node)
    nt.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    bsdf.inputs["Roughness"].default_value = 0.55
    return mat, tex


def image_material(name, image, uv_map):
    mat, tex = uv_texture_material(name, uv_map, "ShaderNodeTexImage")
    tex.image = image
    mat.node_tree.nodes.active = tex
    return mat


def _mesh_arrays(ob, uv_name=None):
    """World-space vertices, loop triangles (vertex indices), their loops, vertex normals
    (world) and, with uv_name, the per-loop UVs of an object's own mesh."""
    me = ob.data
    me.calc_loop_triangles()
    n, m = len(me.vertices), len(me.loop_triangles)
    co = np.empty(n * 3)
    me.vertices.foreach_get("co", co)
    nrm = np.empty(n * 3)
    me.vertices.foreach_get("normal", nrm)
    F = np.empty(m * 3, dtype=np.int64)
    me.loop_triangles.foreach_get("vertices", F)
    L = np.empty(m * 3, dtype=np.int64)
    me.loop_triangles.foreach_get("loops", L)
    M = np.array(ob.matrix_world)
    V = co.reshape(-1, 3) @ M[:3, :3].T + M[:3, 3]
    N = nrm.reshape(-1, 3) @ np.linalg.inv(M[:3, :3])
    N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)
    uv = None
    if uv_name is not None:
        uv = np.empty(len(me.loops) * 2)
        me.uv_layers[uv_name].data.foreach_get("uv", uv)
        uv = uv.reshape(-1, 2)
    return V, F.reshape(m, 3), L.reshape(m, 3), N, uv


def ray_cast_selected_to_active(source, copy, src_uv, src_pixels, uv_map, size, extrusion):
    """Blender's Selected-to-Active bake, done with Blender's ray caster (mathutils BVHTree):
    from each texel's point on `copy` pushed out by `extrusion` along its (interpolated)
    normal, a ray inwards; the first hit on the source gives the colour of the source's image
    there. Used when Cycles' own bake returns a black image (see docs/baking.md).
    Returns (h, w, 4) pixels, bled by 8 texels."""
    from mathutils import Vector
    from mathutils.bvhtree import BVHTree
    from surface_map import texture_bake as TB
    Vs, Fs, Ls, _, suv = _mesh_arrays(source, src_uv)
    Vc, Fc, Lc, Nc, cuv = _mesh_arrays(copy, uv_map)
    tree = BVHTree.FromPolygons(Vs.tolist(), Fs.tolist())   # (plain Python numbers)
    img = np.zeros((size * size, 4))
    hit = np.zeros(size * size, dtype=bool)
    for t, w, texel in TB.rasterize(cuv[Lc], size, size, 1):
        P = np.einsum("ij,ijk->ik", w, Vc[Fc[t]])
        N = np.einsum("ij,ijk->ik", w, Nc[Fc[t]])
        N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)
        O = P + extrusion * N
        for i in range(len(t)):
            loc, _, f, _ = tree.ray_cast(Vector(O[i]), Vector(-N[i]))
            if f is None:
                continue
            tri = Vs[Fs[f]]
            # barycentrics of the hit in its triangle (least squares in 3D)
            A = np.stack([tri[1] - tri[0], tri[2] - tri[0]], 1)
            x = np.linalg.lstsq(A, np.array(loc) - tri[0], rcond=None)[0]
            b = np.array([1 - x[0] - x[1], x[0], x[1]])
            uv = b @ suv[Ls[f]]
            img[texel[i]] = TB.sample_image(src_pixels, uv[None])[0]
            hit[texel[i]] = True
    out, _ = TB.bleed(img.reshape(size, size, 4), hit.reshape(size, size), 8)
    return out.astype(np.float32)


def selected_to_active(demo, source, target, uv_map, src_uv, src_pixels, size=1024):
    """Blender's own bake of the source's image onto a copy of the target: Cycles, Diffuse
    colour, Selected to Active (the copy placed over the source like the Data Transfer copy,
    rays from its surface inflated by a cage extrusion, inwards along its normals). When
    Cycles returns a black image (it does for every shader pass with Debian's Blender 3.4.1
    here), the same rays through mathutils' BVHTree instead. Returns the copy (moved back
    onto the target's place for the render), the seconds and which one was used."""
    copy = bpy.data.objects.new(f"{target.name} (Selected to Active)", target.data.copy())
    bpy.context.scene.collection.objects.link(copy)
    copy.matrix_world = source.matrix_world.copy()
    copy.scale = target.scale
    copy.location = source.location
    img = bpy.data.images.new(f"{copy.name} bake", size, size, alpha=True, float_buffer=True)
    mat = image_material(f"{copy.name} baked", img, uv_map)
    for link in list(mat.node_tree.links):        # the bake target must not feed the shader
        if link.from_node.type == 'TEX_IMAGE':
            mat.node_tree.links.remove(link)
    demo.set_material(copy, mat)
    for ob in bpy.context.view_layer.objects:
        ob.select_set(ob in (source, copy))
    bpy.context.view_layer.objects.active = copy
    bpy.context.view_layer.update()
    scene = bpy.context.scene
    saved = scene.cycles.samples
    scene.cycles.samples = 4
    extrusion = 0.1 * max(copy.dimensions)
    t = time.time()
    bpy.ops.object.bake(type='DIFFUSE', pass_filter={'COLOR'}, use_selected_to_active=True,
                        cage_extrusion=extrusion, max_ray_distance=0.0, margin=8,
                        target='IMAGE_TEXTURES', use_clear=True)
    scene.cycles.samples = saved
    px = np.empty(size * size * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    how = "Cycles bake"
    if float(px.reshape(-1, 4)[:, :3].max()) <= 1e-6:
        print("demo: Cycles' Selected to Active bake gave a black image: the same rays "
              "through mathutils.bvhtree instead")
        px = ray_cast_selected_to_active(source, copy, src_uv, src_pixels, uv_map, size,
                                         extrusion)
        img.pixels.foreach_set(px.ravel())
        how = "ray cast (BVHTree)"
    seconds = time.time() - t
    img.pack()
    tex = next(n for n in mat.node_tree.nodes if n.type == 'TEX_IMAGE')
    mat.node_tree.links.new(tex.outputs["Color"],
                            mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
    copy.matrix_world = target.matrix_world.copy()
    return copy, seconds, how


def seam_spot(source, target, uv_name, view):
    """A point on the target where the image of one of the source's UV seams passes, facing
    the view as much as possible: (world point, world normal)."""
    from surface_map import texture_bake as TB
    Vs, Fs, Ls, _, suv = _mesh_arrays(source, uv_name)
    on = TB.seam_vertices(Fs, suv[Ls], rings=0)
    Vt, Ft, _, Nt, _ = _mesh_arrays(target)
    if target.data.get("surfmap_map", {}).get("flipped", 0):
        Ft = Ft[:, [0, 2, 1]]
    n = len(source.data.vertices)
    face = np.empty(n, dtype=np.int32)
    source.data.attributes["surfmap_map_face"].data.foreach_get("value", face)
    bary = np.empty(n * 3, dtype=np.float32)
    source.data.attributes["surfmap_map_bary"].data.foreach_get("vector", bary)
    bary = bary.reshape(-1, 3).astype(np.float64)
    P = np.einsum("ij,ijk->ik", bary, Vt[Ft[face]])
    N = np.einsum("ij,ijk->ik", bary, Nt[Ft[face]])
    N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)
    d = np.asarray(view, dtype=np.float64)
    score = np.where(on, N @ (d / np.linalg.norm(d)), -np.inf)
    i = int(np.argmax(score))
    return P[i], N[i]


def seam_closeups(demo, source, target, uv_name, shot, transferred, baked):
    """The same close-up of a source seam's image on the target, with the checker through the
    transferred UVs (saw-teeth) and with the baked image (a clean curve)."""
    from mathutils import Vector
    p, nrm = seam_spot(source, target, uv_name, demo.VIEW)
    size = max(target.dimensions)
    frame = demo.marker("seam frame", Vector(p), 0.12 * size)
    frame.hide_render = True
    facing = tuple(Vector(nrm) + Vector(demo.VIEW).normalized() * 0.3)
    for name, mats, text in (("seam_transferred", transferred,
                              "close-up on a source seam's image: checker through the "
                              "transferred UVs"),
                             ("seam_baked", baked, "the same close-up: the baked image")):
        target.data.materials.clear()
        for m in mats:
            target.data.materials.append(m)
        shot(name, [target], direction=facing, fit=[frame], text=text)
    bpy.data.objects.remove(frame, do_unlink=True)


def two_island_uvs(ob, name="UVSplit", base="UVMap"):
    """A UV map `name` from the torus layout `base` (u along the ring in [0, 1]): the ring's two
    halves (polygons by their mean u) as two islands side by side, so the checker does not
    continue across the two straight seams (meridians u = 0 and u = 1/2)."""
    me = ob.data
    L = len(me.loops)
    uv = np.empty(L * 2)
    me.uv_layers[base].data.foreach_get("uv", uv)
    uv = uv.reshape(L, 2)
    start = np.empty(len(me.polygons), dtype=np.int64)
    me.polygons.foreach_get("loop_start", start)
    total = np.empty(len(me.polygons), dtype=np.int64)
    me.polygons.foreach_get("loop_total", total)
    poly = np.repeat(np.arange(len(start)), total)
    mean_u = np.bincount(poly, weights=uv[:, 0]) / total
    second = (mean_u >= 0.5)[poly]
    x = np.where(second, 0.53 + 0.44 * (uv[:, 0] - 0.5) / 0.5, 0.03 + 0.44 * uv[:, 0] / 0.5)
    y = 0.05 + 0.9 * uv[:, 1] / 1.05
    layer = me.uv_layers.get(name) or me.uv_layers.new(name=name)
    layer.data.foreach_set("uv", np.stack([x, y], 1).astype(np.float32).ravel())
    return name


def bake_comparison(demo, source, target, uv_name, shot, out, tag, written):
    """The checker as an image on the source, baked onto the target by Surface Map > Bake
    Textures and by Blender's Selected to Active bake; renders and a side-by-side strip.
    Genus 1: on a layout of two islands (two_island_uvs), whose straight seams the checker
    does not continue across; the transferred UVs show them as saw-teeth, the bake as lines."""
    img = checker_image("demo checker image")
    transferred_image = None
    if tag == "g1":
        uv_name = two_island_uvs(source)
        demo.select_pair(source, target)
        if bpy.ops.surfmap.transfer_uvs() != {'FINISHED'}:
            raise SystemExit("demo.py: transfer_uvs failed")
        transferred_image = [image_material(f"{target.name} checker image (transferred)", img,
                                            f"surfmap {uv_name}")]
    demo.set_material(source, image_material(f"{source.name} checker image", img, uv_name))
    shot("source_image", [source], text=f"source {source.name}: the checker as an image "
                                        f"texture on UV map '{uv_name}' (what the bakes read)")
    demo.select_pair(source, target)
    before = [m for m in target.data.materials]
    if transferred_image is not None:
        demo.set_material(target, transferred_image[0])
        shot("target_transferred_image", [target],
             text=f"the image through the transferred UVs ('surfmap {uv_name}')")
        demo.set_material(target, before[0])
    t = time.time()
    result = bpy.ops.surfmap.bake_textures(resolution=1024, supersample=2, margin=8)
    if result != {'FINISHED'}:
        raise SystemExit(f"demo.py: bake_textures returned {result}")
    status = bpy.context.scene.surfmap.map_status
    print(f"demo: bake_textures in {time.time() - t:.1f}s: {status}")
    fill = status.split("UV map")[-1].split(":")[1].split("%")[0].strip() if ":" in status else "?"
    shot("target_baked", [target],
         text=f"surfmap Bake Textures into the target's own UVs ({fill}% of island texels "
              f"filled)")
    bake_uv = next(l.name for l in target.data.uv_layers if l.name.startswith("surfmap bake")
                   or not l.name.startswith("surfmap "))
    w = img.size[0]
    src_px = np.empty(w * w * 4, dtype=np.float32)
    img.pixels.foreach_get(src_px)
    copy, seconds, how = selected_to_active(demo, source, target, bake_uv, uv_name,
                                            src_px.reshape(w, w, 4))
    print(f"demo: Selected to Active ({how}) in {seconds:.1f}s")
    shot("target_selected_to_active", [copy],
         text=f"Selected to Active ({how}): rays from the target, placed over the source")
    copy.hide_render = True
    copy.hide_set(True)
    baked = [m for m in target.data.materials]
    seam_closeups(demo, source, target, uv_name, shot, transferred_image or before, baked)
    # the target shows the transferred checker again for the shots that follow
    target.data.materials.clear()
    for m in before:
        target.data.materials.append(m)
    names = ("target_datatransfer",
             "target_transferred_image" if transferred_image else "target_transferred",
             "target_baked", "target_selected_to_active")
    paths = [os.path.join(out, f"{tag}_{n}.png") for n in names]
    if all(os.path.exists(p) for p in paths):
        try:
            from PIL import Image
        except ImportError:
            print("demo: no PIL (python3-pil): no side-by-side strip")
            return
        ims = [Image.open(p).convert("RGB") for p in paths]
        w, h = ims[0].size
        strip = Image.new("RGB", (w * len(ims) // 2, h // 2))
        for i, im in enumerate(ims):
            strip.paste(im.resize((w // 2, h // 2)), (i * (w // 2), 0))
        path = os.path.join(out, f"{tag}_bake_comparison.png")
        strip.save(path)
        written.append(path)
        pair = [os.path.join(out, f"{tag}_seam_{n}.png") for n in ("transferred", "baked")]
        ims = [Image.open(p).convert("RGB") for p in pair]
        strip = Image.new("RGB", (w * 2, h))
        for i, im in enumerate(ims):
            strip.paste(im, (i * w, 0))
        path = os.path.join(out, f"{tag}_bake_seams.png")
        strip.save(path)
        written.append(path)


def morph_gif(demo, source, target_name, cam, out, tag, written, frames=12):
    """The source's morph key animated from 0 (frame 0) to 1 (frame frames-1), kept in the
    file as keyframes, rendered at half size and written as a looping GIF (there and back)."""
    scene = bpy.context.scene
    key = source.data.shape_keys.key_blocks[f"surfmap to {target_name}"]
    key.value = 0.0
    key.keyframe_insert("value", frame=0)
    key.value = 1.0
    key.keyframe_insert("value", frame=frames - 1)
    scene.frame_start, scene.frame_end = 0, frames - 1
    demo.show_only([source])
    # the camera: the farther of the fits to the start and the end shape
    best = None
    for f in (0, frames - 1):
        scene.frame_set(f)
        demo.aim(cam, [source], demo.VIEW)
        d = (cam.location - source.matrix_world.translation).length
        if best is None or d > best[0]:
            best = (d, cam.location.copy(), cam.data.clip_start, cam.data.clip_end)
    cam.location, cam.data.clip_start, cam.data.clip_end = best[1], best[2], best[3]
    label = demo.caption(cam, f"{source.name} morphing onto {target_name} (shape key "
                              f"'surfmap to {target_name}' 0 -> 1)")
    saved = (scene.render.resolution_percentage, scene.cycles.samples)
    scene.render.resolution_percentage, scene.cycles.samples = 50, 8
    frame_dir = os.path.join(out, f"{tag}_morph_frames")
    os.makedirs(frame_dir, exist_ok=True)
    paths = []
    for f in range(frames):
        scene.frame_set(f)
        p = os.path.join(frame_dir, f"{f:02d}.png")
        demo.render(p)
        paths.append(p)
    scene.render.resolution_percentage, scene.cycles.samples = saved
    for child in list(label.children):
        bpy.data.objects.remove(child, do_unlink=True)
    bpy.data.objects.remove(label, do_unlink=True)
    scene.frame_set(0)
    try:
        from PIL import Image
    except ImportError:
        print("demo: no PIL (python3-pil): the morph frames stay PNGs in", frame_dir)
        return
    ims = [Image.open(p).convert("RGB") for p in paths]
    seq = ims + ims[-2:0:-1]
    seq = [im.quantize(colors=255, method=Image.Quantize.MEDIANCUT) for im in seq]
    gif = os.path.join(out, f"{tag}_morph.gif")
    durations = [500 if i in (0, frames - 1) else 90 for i in range(len(seq))]
    seq[0].save(gif, save_all=True, append_images=seq[1:], duration=durations, loop=0)
    written.append(gif)
    print(f"demo: wrote {gif} ({len(seq)} frames)")


if __name__ == "__main__":
    raise SystemExit("demo_bake.py is imported by samples/demo.py")
