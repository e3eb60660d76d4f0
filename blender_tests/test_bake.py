"""surfmap.bake_textures: the source's image texture baked into the target's own UV layout
through the stored map (headless)."""
import bpy
import numpy as np

import helpers
from helpers import run, select


def _texture_bake():
    from surface_map import texture_bake
    return texture_bake


def checker_image(name, size=128, cells=8):
    """A byte image: a two-colour checker of cells x cells squares (tiles across the torus
    UV layout's seams)."""
    yy, xx = np.mgrid[0:size, 0:size]
    c = ((xx * cells // size + yy * cells // size) % 2).astype(np.float32)
    px = np.ones((size, size, 4), dtype=np.float32)
    px[..., 0] = 0.1 + 0.8 * c
    px[..., 1] = 0.2 + 0.5 * c
    px[..., 2] = 0.9 - 0.8 * c
    img = bpy.data.images.new(name, size, size, alpha=True)
    img.pixels.foreach_set(px.ravel())
    return img, px


def image_material(name, image):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = image
    nt.links.new(tex.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    return mat


def _pair_with_checker():
    a = helpers.torus("Source", 1.0, 0.5, (-3, 0, 0))
    b = helpers.torus("Target", 1.5, 0.5, (3, 0, 0))
    helpers.set_loop_uvs(a, "UVMap", helpers.torus_uvs(a, 1.0))
    img, px = checker_image("checker")
    a.data.materials.append(image_material("checker", img))
    select([a, b], b)
    return a, b, px


def _stored_inverse(tgt):
    n = len(tgt.data.vertices)
    face = np.empty(n, dtype=np.int32)
    tgt.data.attributes["surfmap_map_face"].data.foreach_get("value", face)
    bary = np.empty(n * 3, dtype=np.float32)
    tgt.data.attributes["surfmap_map_bary"].data.foreach_get("vector", bary)
    return face.astype(np.int64), bary.reshape(-1, 3).astype(np.float64)


def test_bake_refuses_without_a_map():
    a, b, _ = _pair_with_checker()
    before = set(bpy.data.images.keys())
    got, err = run("bake_textures", resolution=64)
    assert got is None and "no stored map" in err, err
    assert set(bpy.data.images.keys()) == before


def test_bake_checker_onto_smart_uv_target():
    TB = _texture_bake()
    a, b, px = _pair_with_checker()
    got, err = run("compute_map")
    assert got == {'FINISHED'}, err
    res = 256
    got, err = run("bake_textures", resolution=res, supersample=2, margin=4)
    assert got == {'FINISHED'}, err
    # the target had no UV map of its own (the transferred 'surfmap UVMap' does not count)
    assert "surfmap bake UV" in b.data.uv_layers
    img = bpy.data.images["surfmap bake Target texture"]
    assert tuple(img.size) == (res, res) and img.packed_file is not None
    mat = b.data.materials[b.data.polygons[0].material_index]
    assert any(n.type == 'TEX_IMAGE' and n.image == img for n in mat.node_tree.nodes)
    baked = np.empty(res * res * 4, dtype=np.float32)
    img.pixels.foreach_get(baked)
    baked = baked.reshape(res, res, 4)
    # every texel inside the target's UV islands is filled (alpha 1; the background is 0)
    Ft, Lt = helpers.triangles_of(b)
    tuv = helpers.loop_uv_array(b, "surfmap bake UV")[Lt]
    islands = TB.island_mask(tuv, res, res)
    filled = baked[..., 3] > 0.999
    frac = float((filled & islands).sum() / islands.sum())
    assert frac > 0.999, frac
    # colour at the target's vertices against the checker at their stored preimages
    Fs, Ls = helpers.triangles_of(a)
    suv = helpers.loop_uv_array(a, "UVMap")[Ls]
    face, bary = _stored_inverse(b)
    want = TB.sample_image(px, np.einsum("ij,ijk->ik", bary, suv[face]))[:, :3]
    have = TB.sample_image(baked, tuv.reshape(-1, 2))[:, :3]
    err = np.abs(have - want[Ft.reshape(-1)]).max(axis=1)
    print(f"    bake: {100 * frac:.2f}% of island texels filled; colour error at target "
          f"vertices mean {err.mean():.4f}, median {np.median(err):.4f}, max {err.max():.3f}")
    assert np.median(err) < 0.02 and err.mean() < 0.06
    # the same check through a wrong correspondence fails (the check can fail)
    wrong = TB.sample_image(px, np.einsum("ij,ijk->ik", np.roll(bary, 5, axis=0),
                                          suv[np.roll(face, 5)]))[:, :3]
    assert np.abs(have - wrong[Ft.reshape(-1)]).max(axis=1).mean() > 0.1


def test_bake_uses_the_targets_own_uv_map():
    a, b, _ = _pair_with_checker()
    helpers.set_loop_uvs(b, "Mine", 0.05 + 0.9 * helpers.torus_uvs(b, 1.5) / 1.1)
    got, err = run("compute_map")
    assert got == {'FINISHED'}, err
    got, err = run("bake_textures", resolution=64, supersample=1, margin=1)
    assert got == {'FINISHED'}, err
    assert "surfmap bake UV" not in b.data.uv_layers
    mat = b.data.materials[b.data.polygons[0].material_index]
    assert any(n.type == 'UVMAP' and n.uv_map == "Mine" for n in mat.node_tree.nodes)
