"""Shared helpers of the Blender tests (not a test file)."""
import os

import bpy
import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SAMPLES = os.path.join(REPO, "samples", "meshes")


def sm():
    """The native surfmap module as the add-on found it (tests fail loudly when missing)."""
    from surface_map import native
    mod = native.load()
    assert mod is not None, f"surfmap native module missing: {native.error()}"
    return mod


def reset_scene():
    if bpy.context.object is not None and bpy.context.object.mode != 'OBJECT':
        bpy.ops.object.mode_set(mode='OBJECT')
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    for coll in (bpy.data.meshes, bpy.data.curves, bpy.data.cameras, bpy.data.lights,
                 bpy.data.materials, bpy.data.collections):
        for block in list(coll):
            coll.remove(block)
    settings = bpy.context.scene.surfmap
    for prop in settings.bl_rna.properties:
        if prop.type == 'COLLECTION':
            getattr(settings, prop.identifier).clear()
        elif prop.identifier not in ("rna_type", "name") and not prop.is_readonly:
            settings.property_unset(prop.identifier)
    from surface_map import map_job
    map_job.ACTIVE["job"] = None


def mesh_object(name, V, F, location=(0, 0, 0)):
    me = bpy.data.meshes.new(name)
    me.from_pydata(np.asarray(V, dtype=float).tolist(), [], np.asarray(F).tolist()
                   if not isinstance(F, list) else F)
    me.update()
    ob = bpy.data.objects.new(name, me)
    ob.location = location
    bpy.context.scene.collection.objects.link(ob)
    return ob


def torus_of_revolution(R, r, n_major, n_minor):
    """Triangulated torus around z (the same surface as surfmap.shapes.torus_of_revolution)."""
    u = 2 * np.pi * np.arange(n_major) / n_major
    v = 2 * np.pi * np.arange(n_minor) / n_minor
    U, W = np.meshgrid(u, v, indexing="ij")
    V = np.stack([(R + r * np.cos(W)) * np.cos(U), (R + r * np.cos(W)) * np.sin(U),
                  r * np.sin(W)], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_major), np.arange(n_minor), indexing="ij")
    a = i * n_minor + j
    b = ((i + 1) % n_major) * n_minor + j
    c = ((i + 1) % n_major) * n_minor + (j + 1) % n_minor
    d = i * n_minor + (j + 1) % n_minor
    F = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                        np.stack([a, c, d], -1).reshape(-1, 3)])
    return V, F


def torus(name, R=1.0, r=0.5, location=(0, 0, 0)):
    shapes = getattr(sm(), "shapes", None)
    if shapes is not None and hasattr(shapes, "torus_of_revolution"):
        V, F = shapes.torus_of_revolution(R, r, 48, 24)
    else:
        V, F = torus_of_revolution(R, r, 48, 24)
    return mesh_object(name, V, F, location)


def voxel_surface(filled):
    """Closed quad surface of a set of unit voxels (i, j, k): one quad per voxel face whose
    neighbour is empty, vertices shared on the integer lattice, faces outward."""
    filled = set(filled)
    index, V, polys = {}, [], []

    def vid(p):
        if p not in index:
            index[p] = len(V)
            V.append(p)
        return index[p]
    for (i, j, k) in sorted(filled):
        for axis in range(3):
            for s in (0, 1):
                n = [i, j, k]
                n[axis] += 1 if s else -1
                if tuple(n) in filled:
                    continue
                u, w = (axis + 1) % 3, (axis + 2) % 3
                corners = []
                for du, dw in ((0, 0), (1, 0), (1, 1), (0, 1)):
                    c = [i, j, k]
                    c[axis] += s
                    c[u] += du
                    c[w] += dw
                    corners.append(vid(tuple(c)))
                polys.append(corners if s else corners[::-1])
    return np.array(V, dtype=float), polys


def polycube_double_torus(k=3):
    """A genus-2 slab (5 x 3 x 1 blocks of k^3 voxels with two 1-block holes), triangulated."""
    holes = {(1, 1), (3, 1)}
    filled = [(i, j, z) for i in range(5 * k) for j in range(3 * k) for z in range(k)
              if (i // k, j // k) not in holes]
    V, polys = voxel_surface(filled)
    F = [[p[0], p[1], p[2]] for p in polys] + [[p[0], p[2], p[3]] for p in polys]
    return V / k, np.array(F)


def double_torus(name, location=(0, 0, 0)):
    shapes = getattr(sm(), "shapes", None)
    if shapes is not None and hasattr(shapes, "n_hole_torus"):
        V, F = shapes.n_hole_torus(2)
    else:
        V, F = polycube_double_torus()
    return mesh_object(name, V, F, location)


def select(objs, active):
    for ob in bpy.context.view_layer.objects:
        ob.select_set(False)
    for ob in objs:
        ob.select_set(True)
    bpy.context.view_layer.objects.active = active


def mesh_snapshot(ob):
    me = ob.data
    co = np.empty(len(me.vertices) * 3)
    me.vertices.foreach_get("co", co)
    faces = [tuple(p.vertices) for p in me.polygons]
    seams = [e.index for e in me.edges if e.use_seam]
    return co.tobytes(), faces, seams


def scene_snapshot():
    """Everything an operator that cancels must leave untouched."""
    return {
        "objects": sorted(o.name for o in bpy.data.objects),
        "collections": sorted(c.name for c in bpy.data.collections),
        "curves": sorted(c.name for c in bpy.data.curves),
        "materials": sorted(m.name for m in bpy.data.materials),
        "meshes": {o.name: mesh_snapshot(o) for o in bpy.data.objects if o.type == 'MESH'},
        "attributes": {o.name: sorted(a.name for a in o.data.attributes)
                       for o in bpy.data.objects if o.type == 'MESH'},
        "uv_layers": {o.name: [u.name for u in o.data.uv_layers]
                      for o in bpy.data.objects if o.type == 'MESH'},
        "shape_keys": {o.name: [k.name for k in o.data.shape_keys.key_blocks]
                       if o.data.shape_keys else [] for o in bpy.data.objects
                       if o.type == 'MESH'},
        "id_props": {o.name: sorted(o.data.keys()) for o in bpy.data.objects
                     if o.type == 'MESH'},
    }


def run_op():
    """Runs show_cut_loops; returns (result set, None) or (None, error text)."""
    try:
        return bpy.ops.surfmap.show_cut_loops(), None
    except RuntimeError as e:
        return None, str(e)


def loop_curves(ob):
    return sorted((o for o in bpy.data.objects if o.get("surfmap_loops_of") == ob.name),
                  key=lambda o: o.name)


def seam_graph(ob):
    """(vertices, edges) of the edges marked as seams."""
    edges = [tuple(sorted(e.vertices)) for e in ob.data.edges if e.use_seam]
    verts = sorted({v for e in edges for v in e})
    return verts, edges


def faces_connected_across_non_seams(ob):
    """True when the faces stay one piece after cutting along the seams."""
    me = ob.data
    edge_faces = {}
    for p in me.polygons:
        for ek in p.edge_keys:
            edge_faces.setdefault(ek, []).append(p.index)
    seams = {tuple(sorted(e.vertices)) for e in me.edges if e.use_seam}
    parent = list(range(len(me.polygons)))

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a
    for ek, fs in edge_faces.items():
        if ek in seams:
            continue
        for f in fs[1:]:
            parent[find(f)] = find(fs[0])
    return len({find(i) for i in range(len(me.polygons))}) == 1


def load_sample(name, location=(0, 0, 0)):
    """A shipped sample mesh (samples/meshes/NAME.obj) as an object, read by the native module."""
    V, polys = sm().read_polygon_soup(os.path.join(SAMPLES, name + ".obj"))
    return mesh_object(name, np.asarray(V), [list(p) for p in polys], location)


def loop_uv_array(ob, name=None):
    me = ob.data
    layer = me.uv_layers[name] if name else me.uv_layers.active
    a = np.empty(len(me.loops) * 2)
    layer.data.foreach_get("uv", a)
    return a.reshape(-1, 2)


def set_loop_uvs(ob, name, uv):
    layer = ob.data.uv_layers.get(name) or ob.data.uv_layers.new(name=name)
    layer.data.foreach_set("uv", np.asarray(uv, dtype=np.float32).ravel())
    return layer


def torus_uvs(ob, R):
    """Per-corner (u, v) of a torus of revolution around z with major radius R: the classic
    rectangle layout, one island with seams along u = 0 and v = 0 (UVs unwrapped per polygon)."""
    me = ob.data
    co = np.array([v.co for v in me.vertices])
    lv = np.array([l.vertex_index for l in me.loops])
    P = co[lv]
    u = np.arctan2(P[:, 1], P[:, 0]) / (2 * np.pi) % 1.0
    v = np.arctan2(P[:, 2], np.hypot(P[:, 0], P[:, 1]) - R) / (2 * np.pi) % 1.0
    for p in me.polygons:
        s = slice(p.loop_start, p.loop_start + p.loop_total)
        for a in (u, v):
            a[s] = np.where(a[s].max() - a[s] > 0.5, a[s] + 1.0, a[s])
    return np.stack([u, v], axis=1)


def box_uvs(ob):
    """Cube projection per polygon (like Blender's Cube Projection): each polygon is projected
    along the axis its normal is closest to, mirrored so that every island keeps the outward
    orientation; islands are scaled into their own cell of a 3x2 grid. Many islands, no flips."""
    me = ob.data
    co = np.array([v.co for v in me.vertices])
    lo, hi = co.min(axis=0), co.max(axis=0)
    size = float((hi - lo).max()) or 1.0
    uv = np.zeros((len(me.loops), 2))
    for p in me.polygons:
        n = np.array(p.normal)
        ax = int(np.argmax(np.abs(n)))
        sgn = 1.0 if n[ax] > 0 else -1.0
        u_ax, v_ax = (ax + 1) % 3, (ax + 2) % 3
        cell = ax * 2 + (0 if sgn > 0 else 1)
        for li in range(p.loop_start, p.loop_start + p.loop_total):
            x = co[me.loops[li].vertex_index]
            uu = (x[u_ax] - lo[u_ax]) / size
            vv = (x[v_ax] - lo[v_ax]) / size
            if sgn < 0:
                uu = 1.0 - uu
            uv[li] = ((cell % 3) + 0.05 + 0.9 * uu) / 3.0, ((cell // 3) + 0.05 + 0.9 * vv) / 2.0
    return uv


def run(op, **kw):
    """Runs bpy.ops.surfmap.<op>; returns (result set, None) or (None, error text)."""
    try:
        return getattr(bpy.ops.surfmap, op)(**kw), None
    except RuntimeError as e:
        return None, str(e)


def triangles_of(ob):
    """(F (m,3) vertex indices, loops (m,3)) of Blender's loop triangles."""
    me = ob.data
    me.calc_loop_triangles()
    m = len(me.loop_triangles)
    F = np.empty(m * 3, dtype=np.int64)
    L = np.empty(m * 3, dtype=np.int64)
    me.loop_triangles.foreach_get("vertices", F)
    me.loop_triangles.foreach_get("loops", L)
    return F.reshape(m, 3), L.reshape(m, 3)


def coords(ob):
    me = ob.data
    co = np.empty(len(me.vertices) * 3)
    me.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def _compact(V, F):
    used = np.unique(F)
    remap = -np.ones(len(V), dtype=np.int64)
    remap[used] = np.arange(len(used))
    return V[used], remap[F]


def _gauss(x, z, x0, z0, sx, sz):
    return np.exp(-((x - x0) / sx) ** 2 - ((z - z0) / sz) ** 2)


def open_head(subdivisions=4):
    """An open head (genus 0, one boundary loop: the neck), facing -y, z up: an icosphere made
    an ellipsoid (0.78 wide, 0.92 deep, 1.1 high) with a nose, brows and a chin pushed out of its
    front, the faces below the jaw removed. For the open head / mask checks (docs/open_surfaces.md
    "In Blender: an open head and a mask")."""
    V, F = sm().shapes.sphere(subdivisions)
    V, F = np.asarray(V, dtype=float), np.asarray(F, dtype=np.int64)
    x, y, z = V.T
    front = np.clip(-y, 0, None) ** 2
    out = (0.30 * _gauss(x, z, 0, -0.05, 0.13, 0.22) + 0.10 * _gauss(np.abs(x), z, 0.3, 0.32, 0.18, 0.08)
           + 0.12 * _gauss(x, z, 0, -0.62, 0.28, 0.14)) * front
    W = np.stack([0.78 * x, 0.92 * y - out, 1.1 * z], axis=1)
    c = V[F].mean(axis=1)
    return _compact(W, F[c[:, 2] > -0.72])


def open_mask(subdivisions=4, centre=(0.0, 0.0, 0.0), size=(1.0, 1.0, 1.0)):
    """An open face mask (genus 0, one boundary loop), facing -y: the front of a flatter
    ellipsoid than open_head's, with a longer nose and no chin, inside an oval outline from the
    brows to the mouth; `size` scales it (x, y, z) and `centre` moves it, so that it can be fitted
    over another face (the same frame as open_head at the defaults)."""
    V, F = sm().shapes.sphere(subdivisions)
    V, F = np.asarray(V, dtype=float), np.asarray(F, dtype=np.int64)
    x, y, z = V.T
    front = np.clip(-y, 0, None) ** 2
    out = (0.38 * _gauss(x, z, 0, 0.0, 0.11, 0.28) + 0.06 * _gauss(np.abs(x), z, 0.32, 0.3, 0.2, 0.1)) * front
    W = np.stack([0.8 * x, 0.75 * y - 0.2 - out, 1.0 * z + 0.1], axis=1)
    W = W * np.asarray(size, dtype=float) + np.asarray(centre, dtype=float)
    c = V[F].mean(axis=1)
    c /= np.linalg.norm(c, axis=1)[:, None]
    keep = (c[:, 1] < -0.2) & ((c[:, 0] / 0.85) ** 2 + ((c[:, 2] + 0.05) / 0.75) ** 2 < 1)
    return _compact(W, F[keep])
