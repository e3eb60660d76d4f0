"""The bpy half of the data path: reading an object's mesh and writing results into the scene
(seams, loop curves in a collection, pair-coloured materials). No algorithms here."""
import bpy
import numpy as np

from . import cut_loops

OWNER_KEY = "surfmap_loops_of"      # custom property on the curve objects we create
SEAM_LAYER = "surfmap_loop_seam"     # bool edge attribute: the seams this add-on marked


def read_object_mesh(obj, depsgraph):
    """Local-space mesh of a mesh object, triangulated with Blender's loop triangles (which
    handle concave polygons). Uses the evaluated mesh when the object has modifiers.

    Returns dict(V (n,3) float64, F (m,3) int32, tri_polygon (m,), tri_loops (m,3) (the mesh
    loops, i.e. face corners, of each triangle corner), num_polygons, evaluated (bool)).
    """
    evaluated = any(m.show_viewport for m in obj.modifiers)
    if evaluated:
        ob_eval = obj.evaluated_get(depsgraph)
        mesh = ob_eval.to_mesh()
    else:
        ob_eval, mesh = None, obj.data
    try:
        n = len(mesh.vertices)
        V = np.empty(n * 3, dtype=np.float64)
        mesh.vertices.foreach_get("co", V)
        mesh.calc_loop_triangles()
        m = len(mesh.loop_triangles)
        F = np.empty(m * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", F)
        L = np.empty(m * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("loops", L)
        P = np.empty(m, dtype=np.int32)
        mesh.loop_triangles.foreach_get("polygon_index", P)
        return {"V": V.reshape(n, 3), "F": F.reshape(m, 3), "tri_loops": L.reshape(m, 3),
                "tri_polygon": P, "num_polygons": len(mesh.polygons), "evaluated": evaluated}
    finally:
        if ob_eval is not None:
            ob_eval.to_mesh_clear()


def mark_seams(mesh, seam_edges):
    """Marks the given vertex pairs as seams on `mesh`. The seams this add-on marked in an
    earlier run (remembered in the SEAM_LAYER edge attribute) are cleared first; seams the
    user marked are left alone. Returns the number of edges marked."""
    ne = len(mesh.edges)
    keys = np.empty(ne * 2, dtype=np.int64)
    mesh.edges.foreach_get("vertices", keys)
    keys = keys.reshape(ne, 2)
    seam = np.empty(ne, dtype=bool)
    mesh.edges.foreach_get("use_seam", seam)
    layer = mesh.attributes.get(SEAM_LAYER)
    if layer is not None and layer.domain == 'EDGE' and layer.data_type == 'BOOLEAN':
        ours = np.empty(ne, dtype=bool)
        layer.data.foreach_get("value", ours)
        seam &= ~ours
    elif layer is not None:
        mesh.attributes.remove(layer)
        layer = None
    index = {(min(a, b), max(a, b)): i for i, (a, b) in enumerate(keys.tolist())}
    ours = np.zeros(ne, dtype=bool)
    for e in seam_edges:
        i = index.get((int(e[0]), int(e[1])))
        if i is not None:
            ours[i] = True
    seam |= ours
    mesh.edges.foreach_set("use_seam", seam)
    if layer is None:
        layer = mesh.attributes.new(SEAM_LAYER, 'BOOLEAN', 'EDGE')
    layer.data.foreach_set("value", ours)
    mesh.update()
    return int(ours.sum())


def loop_material(name, rgba):
    """A material per loop name ('SurfMap a1'), shared by all objects, coloured per pair."""
    mat_name = f"SurfMap {name}"
    mat = bpy.data.materials.get(mat_name)
    if mat is None:
        mat = bpy.data.materials.new(mat_name)
        mat.use_nodes = True
    mat.diffuse_color = rgba
    nodes = mat.node_tree.nodes if mat.node_tree else None
    bsdf = nodes.get("Principled BSDF") if nodes else None
    if bsdf is not None:
        bsdf.inputs["Base Color"].default_value = rgba
        bsdf.inputs["Roughness"].default_value = 0.35
        # Blender 4.0 renamed the Principled BSDF's "Emission" input "Emission Color" (its
        # default then white: left as it is, the curves would glow white, not in their colour)
        for emission in ("Emission Color", "Emission"):
            if emission in bsdf.inputs:
                bsdf.inputs[emission].default_value = rgba
                break
        if "Emission Strength" in bsdf.inputs:
            bsdf.inputs["Emission Strength"].default_value = 0.35
    return mat


def remove_loop_curves(obj_name):
    """Removes the loop curves made earlier for the object named obj_name. Returns count."""
    removed = 0
    for ob in list(bpy.data.objects):
        if ob.get(OWNER_KEY) == obj_name:
            data = ob.data
            bpy.data.objects.remove(ob, do_unlink=True)
            if data is not None and data.users == 0 and isinstance(data, bpy.types.Curve):
                bpy.data.curves.remove(data)
            removed += 1
    return removed


def loops_collection(scene, obj):
    """The collection '<object> loops', created and linked under the scene when missing."""
    name = f"{obj.name} loops"
    coll = bpy.data.collections.get(name)
    if coll is None:
        coll = bpy.data.collections.new(name)
    if coll not in scene.collection.children_recursive[:]:
        scene.collection.children.link(coll)
    return coll


LOOP_TRI_KEY = "surfmap_loop_vertices"    # curve object: 3 mesh vertices per curve point
LOOP_BARY_KEY = "surfmap_loop_weights"    # ... and their barycentric weights
LOOP_SIG_KEY = "surfmap_loop_shape"       # the owner's shape-key values the points follow


def add_loop_curves(scene, obj, curves, bevel, weights=None, colours=None):
    """One cyclic poly curve object per loop, named '<object> a1', ..., points in the
    object's local space and parented to it (so they follow its transform). weights: per
    curve, (vertices (k,3), barycentrics (k,3)) of its points on the mesh, kept on the curve
    so follow_shape_keys can move the points with the mesh's shape keys (the morph).
    colours: per curve RGBA (default: by the loop pair of names 'a<k>' / 'b<k>')."""
    remove_loop_curves(obj.name)
    coll = loops_collection(scene, obj)
    made = []
    for c, (name, pts) in enumerate(curves):
        cu = bpy.data.curves.new(f"{obj.name} {name}", 'CURVE')
        cu.dimensions = '3D'
        cu.bevel_depth = bevel
        cu.bevel_resolution = 3
        cu.use_fill_caps = True
        sp = cu.splines.new('POLY')
        sp.points.add(len(pts) - 1)
        co = np.ones((len(pts), 4), dtype=np.float64)
        co[:, :3] = pts
        sp.points.foreach_set("co", co.ravel())
        sp.use_cyclic_u = True
        if colours is not None:
            rgba = colours[c]
        else:
            rgba = cut_loops.pair_colour(int(name[1:]) * 2 - 2 + (0 if name[0] == "a" else 1))
        cu.materials.append(loop_material(name, rgba))
        ob = bpy.data.objects.new(f"{obj.name} {name}", cu)
        ob[OWNER_KEY] = obj.name
        if weights is not None:
            ob[LOOP_TRI_KEY] = np.asarray(weights[c][0], dtype=np.int32).ravel().tolist()
            ob[LOOP_BARY_KEY] = np.asarray(weights[c][1], dtype=np.float64).ravel().tolist()
        coll.objects.link(ob)
        ob.parent = obj
        ob.matrix_parent_inverse.identity()
        ob.matrix_basis.identity()
        made.append(ob)
    return made


# --- the map's inputs and outputs -------------------------------------------------------------

LAYERS_KEY = "surfmap_layers"      # mesh ID property: names of the layers this add-on wrote
CORR_FACE = "surfmap_map_face"      # INT point attribute: face of the partner's triangles
CORR_BARY = "surfmap_map_bary"      # FLOAT_VECTOR point attribute: barycentrics there
CORR_KEY = "surfmap_map"            # mesh ID property group: partner, fingerprints, summary
CORR_FACE_INITIAL = "surfmap_map_initial_face"   # the same for the initial map (genus >= 1)
CORR_BARY_INITIAL = "surfmap_map_initial_bary"
DILATATION = "surfmap_dilatation"   # FLOAT face attribute: D' of the optimised map
DILATATION_INITIAL = "surfmap_dilatation_initial"


def read_map_mesh(obj, depsgraph):
    """read_object_mesh plus what the map's outputs need: the polygon layout (loop_start,
    loop_total, loop_vertex), whether the evaluated mesh has the object's own topology, the UV
    maps as per-loop arrays {name: (L,2)}, and the vertex groups {name: (indices, weights)}."""
    d = read_object_mesh(obj, depsgraph)
    evaluated = d["evaluated"]
    if evaluated:
        ob_eval = obj.evaluated_get(depsgraph)
        mesh = ob_eval.to_mesh(preserve_all_data_layers=True, depsgraph=depsgraph)
    else:
        ob_eval, mesh = None, obj.data
    try:
        P = len(mesh.polygons)
        L = len(mesh.loops)
        start = np.empty(P, dtype=np.int64)
        total = np.empty(P, dtype=np.int64)
        lv = np.empty(L, dtype=np.int64)
        mesh.polygons.foreach_get("loop_start", start)
        mesh.polygons.foreach_get("loop_total", total)
        mesh.loops.foreach_get("vertex_index", lv)
        uvs = {}
        for layer in mesh.uv_layers:
            a = np.empty(L * 2, dtype=np.float64)
            layer.data.foreach_get("uv", a)
            uvs[layer.name] = a.reshape(L, 2)
        groups = {}
        names = {g.index: g.name for g in obj.vertex_groups}
        if names:
            for v in mesh.vertices:
                for g in v.groups:
                    name = names.get(g.group)
                    if name is not None:
                        groups.setdefault(name, ([], []))
                        groups[name][0].append(v.index)
                        groups[name][1].append(g.weight)
            for name in names.values():
                groups.setdefault(name, ([], []))
        same = True
        if evaluated:
            own = obj.data
            if len(own.vertices) != len(mesh.vertices) or len(own.loops) != L or \
                    len(own.polygons) != P:
                same = False
            else:
                lv_own = np.empty(L, dtype=np.int64)
                own.loops.foreach_get("vertex_index", lv_own)
                same = bool(np.array_equal(lv_own, lv))
        d.update(loop_start=start, loop_total=total, loop_vertex=lv, uv_layers=uvs,
                 vertex_groups=groups, same_topology=same)
        return d
    finally:
        if ob_eval is not None:
            ob_eval.to_mesh_clear()


def selected_vertex_order(mesh):
    """Selected vertices (the mesh's own flags) in the order they were selected (the mesh's
    selection history), then the other selected ones in index order."""
    import bmesh
    sel = np.zeros(len(mesh.vertices), dtype=bool)
    mesh.vertices.foreach_get("select", sel)
    bm = bmesh.new()
    try:
        bm.from_mesh(mesh)
        hist = [e.index for e in bm.select_history
                if isinstance(e, bmesh.types.BMVert) and sel[e.index]]
    finally:
        bm.free()
    seen = set(hist)
    return hist + [int(i) for i in np.nonzero(sel)[0] if int(i) not in seen]


def applied_copy(obj, depsgraph, name):
    """A new object holding obj's evaluated mesh (modifiers applied), same transform and
    collections, for outputs that need that mesh's own topology."""
    ob_eval = obj.evaluated_get(depsgraph)
    me = bpy.data.meshes.new_from_object(ob_eval, preserve_all_data_layers=True,
                                         depsgraph=depsgraph)
    me.name = name
    ob = bpy.data.objects.new(name, me)
    ob.matrix_world = obj.matrix_world.copy()
    for coll in obj.users_collection:
        coll.objects.link(ob)
    return ob


def _ours(mesh):
    return list(mesh.get(LAYERS_KEY, []))


def _remember(mesh, kind, name):
    names = _ours(mesh)
    tag = f"{kind}:{name}"
    if tag not in names:
        names.append(tag)
        mesh[LAYERS_KEY] = names


def _layer_name(mesh, kind, wanted, existing):
    """`wanted`, or when a layer of that name exists that this add-on did not write, the first
    free 'wanted.001', ... (nothing of the user's is overwritten)."""
    ours = set(_ours(mesh))
    name, i = wanted, 0
    while name in existing and f"{kind}:{name}" not in ours:
        i += 1
        name = f"{wanted}.{i:03d}"
    return name


def write_attribute(mesh, name, values, data_type='FLOAT_VECTOR', domain='POINT'):
    a = mesh.attributes.get(name)
    if a is not None and (a.data_type != data_type or a.domain != domain):
        mesh.attributes.remove(a)
        a = None
    if a is None:
        a = mesh.attributes.new(name, data_type, domain)
    key = "vector" if data_type == 'FLOAT_VECTOR' else "value"
    a.data.foreach_set(key, np.ascontiguousarray(values, dtype=np.float32 if data_type != 'INT'
                                                 else np.int32).ravel())
    return a


def write_correspondence(mesh, face, bary, meta, initial=None):
    """Per vertex: the partner's triangle and barycentrics (survive saving); meta (dict of
    str/int/float) as the mesh's CORR_KEY ID property. initial: (face, bary) of the initial
    map, kept so the "before" outputs can be made again without a solve; None removes an
    initial map stored by an earlier run (it would belong to another map)."""
    write_attribute(mesh, CORR_FACE, np.asarray(face, dtype=np.int32), 'INT')
    write_attribute(mesh, CORR_BARY, np.asarray(bary, dtype=np.float32))
    if initial is not None:
        write_attribute(mesh, CORR_FACE_INITIAL, np.asarray(initial[0], dtype=np.int32), 'INT')
        write_attribute(mesh, CORR_BARY_INITIAL, np.asarray(initial[1], dtype=np.float32))
    else:
        for name in (CORR_FACE_INITIAL, CORR_BARY_INITIAL):
            a = mesh.attributes.get(name)
            if a is not None:
                mesh.attributes.remove(a)
    mesh[CORR_KEY] = dict(meta, has_initial=int(initial is not None))


def _read_point_map(mesh, face_name, bary_name):
    a, b = mesh.attributes.get(face_name), mesh.attributes.get(bary_name)
    if a is None or b is None:
        return None
    n = len(mesh.vertices)
    if len(a.data) != n or len(b.data) != n or a.data_type != 'INT' or b.data_type != 'FLOAT_VECTOR':
        return None
    face = np.empty(n, dtype=np.int32)
    a.data.foreach_get("value", face)
    bary = np.empty(n * 3, dtype=np.float32)
    b.data.foreach_get("vector", bary)
    return face.astype(np.int64), bary.reshape(n, 3).astype(np.float64)


def read_correspondence(mesh):
    """(face (n,), bary (n,3), meta dict) or None when the mesh has no stored map."""
    meta = mesh.get(CORR_KEY)
    got = _read_point_map(mesh, CORR_FACE, CORR_BARY)
    if got is None or meta is None:
        return None
    return got[0], got[1], meta.to_dict()


def read_initial_correspondence(mesh):
    """(face (n,), bary (n,3)) of the stored initial map, or None (none stored, e.g. genus 0,
    or a map stored by an older version of the add-on)."""
    meta = mesh.get(CORR_KEY)
    if meta is None or not meta.get("has_initial", 0):
        return None
    return _read_point_map(mesh, CORR_FACE_INITIAL, CORR_BARY_INITIAL)


def write_face_float(mesh, name, values):
    write_attribute(mesh, name, np.asarray(values, dtype=np.float32), 'FLOAT', 'FACE')


def read_face_float(mesh, name):
    a = mesh.attributes.get(name)
    if a is None or a.domain != 'FACE' or a.data_type != 'FLOAT' or len(a.data) != len(mesh.polygons):
        return None
    v = np.empty(len(mesh.polygons), dtype=np.float32)
    a.data.foreach_get("value", v)
    return v.astype(np.float64)


def write_uv_map(mesh, wanted, loop_uv):
    """A UV map named `wanted` (or a free variant) holding loop_uv (L,2). Returns its name, or
    None when the mesh already has the maximum number of UV maps."""
    existing = [u.name for u in mesh.uv_layers]
    name = _layer_name(mesh, "uv", wanted, existing)
    layer = mesh.uv_layers.get(name)
    if layer is None:
        if len(mesh.uv_layers) >= 8:
            return None
        layer = mesh.uv_layers.new(name=name, do_init=False)
        if layer is None:
            return None
    layer.data.foreach_set("uv", np.ascontiguousarray(loop_uv, dtype=np.float32).ravel())
    _remember(mesh, "uv", name)
    return name


def free_uv_slots(mesh, wanted_names):
    """How many of wanted_names need a new UV map (not already one of ours) and whether they fit."""
    ours = set(_ours(mesh))
    need = sum(1 for w in wanted_names if f"uv:{w}" not in ours or mesh.uv_layers.get(w) is None)
    return need <= 8 - len(mesh.uv_layers), need


def write_colour(mesh, wanted, rgba, domain):
    """A FLOAT_COLOR attribute (domain 'POINT' or 'CORNER') named `wanted` (or a free
    variant). Returns its name."""
    existing = [a.name for a in mesh.attributes]
    name = _layer_name(mesh, "colour", wanted, existing)
    a = mesh.attributes.get(name)
    if a is not None:
        mesh.attributes.remove(a)
    a = mesh.color_attributes.new(name, 'FLOAT_COLOR', domain)
    a.data.foreach_set("color", np.ascontiguousarray(rgba, dtype=np.float32).ravel())
    _remember(mesh, "colour", name)
    return name


def write_shape_key(obj, wanted, co):
    """A shape key named `wanted` (or a free variant) with the given local coordinates; a
    'Basis' key from the current mesh is added first when the object has none. The new key's
    value is left at 0 (slide it to 1 for the morph). Returns its name."""
    mesh = obj.data
    if mesh.shape_keys is None:
        obj.shape_key_add(name="Basis", from_mix=False)
    blocks = mesh.shape_keys.key_blocks
    name = _layer_name(mesh, "shape", wanted, [k.name for k in blocks])
    key = blocks.get(name)
    if key is None:
        key = obj.shape_key_add(name=name, from_mix=False)
    key.data.foreach_set("co", np.ascontiguousarray(co, dtype=np.float32).ravel())
    key.value = 0.0
    key.slider_min, key.slider_max = 0.0, 1.0
    _remember(mesh, "shape", name)
    mesh.update()
    return name


def matrix_np(m):
    return np.array([list(r) for r in m], dtype=np.float64)


REFINED_KEY = "surfmap_refined_of"   # object property: the refined morph object of <source>


def refined_morph_object(source_obj, src, tgt, image, image_face, morph_matrix, key_name,
                         max_bend=0.02, rounds=4):
    """The source refined where its image is long or bends (docs/method.md §2.12), as a new object
    '<source> refined morph' (replacing the one made earlier) with the source's UV maps and
    materials and a shape key onto the target. Returns (object, refinement dict)."""
    from mathutils import Vector
    from mathutils.bvhtree import BVHTree

    from . import geometry, morph
    Vt, Ft = tgt["V"], tgt["F"]
    bvh = BVHTree.FromPolygons(Vt.tolist(), Ft.tolist(), all_triangles=True)
    FN = geometry.face_normals(Vt, Ft)
    FN /= np.maximum(np.linalg.norm(FN, axis=1), 1e-300)[:, None]

    def project(P):
        pos = np.empty((len(P), 3))
        nrm = np.empty((len(P), 3))
        for i, p in enumerate(P):
            loc, _, idx, _ = bvh.find_nearest(Vector(p))
            pos[i] = loc
            nrm[i] = FN[idx]
        return pos, nrm
    e = np.concatenate([Ft[:, [0, 1]], Ft[:, [1, 2]], Ft[:, [2, 0]]])
    max_len = float(np.median(np.linalg.norm(Vt[e[:, 0]] - Vt[e[:, 1]], axis=1)))
    r = morph.refine_for_morph(src["V"], src["F"], image, FN[image_face], project, max_len,
                                 max_bend=max_bend, rounds=rounds)
    for ob in list(bpy.data.objects):
        if ob.get(REFINED_KEY) == source_obj.name:
            me_old = ob.data
            bpy.data.objects.remove(ob, do_unlink=True)
            if me_old is not None and me_old.users == 0:
                bpy.data.meshes.remove(me_old)
    name = f"{source_obj.name} refined morph"
    me = bpy.data.meshes.new(name)
    me.from_pydata(r["V"].tolist(), [], r["F"].tolist())
    for uv_name, loop_uv in src["uv_layers"].items():
        cu = src.corner_uvs(loop_uv)[r["origin_face"]]          # (m',3,2)
        uv = np.einsum("tkj,tjx->tkx", r["origin_bary"], cu)
        layer = me.uv_layers.new(name=uv_name)
        layer.data.foreach_set("uv", uv.astype(np.float32).ravel())
    for mat in source_obj.data.materials:
        me.materials.append(mat)
    own = source_obj.data
    if len(own.polygons) == src["num_polygons"] and len(own.polygons):
        mi = np.empty(len(own.polygons), dtype=np.int32)
        own.polygons.foreach_get("material_index", mi)
        me.polygons.foreach_set("material_index",
                                mi[np.asarray(src["tri_polygon"])[r["origin_face"]]])
        smooth = bool(own.polygons[0].use_smooth)
        me.polygons.foreach_set("use_smooth", np.full(len(me.polygons), smooth))
    me.update()
    ob = bpy.data.objects.new(name, me)
    ob[REFINED_KEY] = source_obj.name
    ob.matrix_world = source_obj.matrix_world.copy()
    for coll in source_obj.users_collection:
        coll.objects.link(ob)
    ob.shape_key_add(name="Basis", from_mix=False)
    key = ob.shape_key_add(name=key_name, from_mix=False)
    from .geometry import apply_matrix
    key.data.foreach_set("co", apply_matrix(morph_matrix, r["image"]).astype(np.float32).ravel())
    key.value = 0.0
    return ob, r


RAW_PREFIX = "surfmap_raw "   # FLOAT attribute: the values behind a colour output (recolouring)


def write_raw_values(mesh, colour_name, values, domain):
    """The values a colour attribute was made from ('FACE' or 'POINT'), so the legend's range
    can be changed later without a solve. Infinite values (flipped faces) are kept."""
    name = RAW_PREFIX + colour_name
    write_attribute(mesh, name, np.asarray(values, dtype=np.float32), 'FLOAT', domain)
    _remember(mesh, "raw", name)


def read_raw_values(mesh, colour_name):
    """(values, domain) written by write_raw_values, or None."""
    a = mesh.attributes.get(RAW_PREFIX + colour_name)
    if a is None or a.data_type != 'FLOAT':
        return None
    v = np.empty(len(a.data), dtype=np.float32)
    a.data.foreach_get("value", v)
    return v.astype(np.float64), a.domain


def _shape_signature(owner):
    keys = owner.data.shape_keys if owner.type == 'MESH' else None
    if keys is None:
        return ""
    return ";".join(f"{k.name}={k.value:.6f}{'m' if k.mute else ''}" for k in keys.key_blocks)


def follow_shape_keys(depsgraph=None):
    """Moves the loop curves' points with their mesh's shape keys (e.g. the morph slider):
    each point is a fixed combination of three of the mesh's vertices, evaluated on the mesh
    with its shape keys. Only curves whose owner's shape-key values changed are touched.
    Returns the number of curves moved."""
    moved = 0
    cache = {}
    for ob in bpy.data.objects:
        tri = ob.get(LOOP_TRI_KEY)
        owner = bpy.data.objects.get(ob.get(OWNER_KEY, "")) if tri is not None else None
        if owner is None or owner.type != 'MESH' or ob.type != 'CURVE':
            continue
        sig = _shape_signature(owner)
        if ob.get(LOOP_SIG_KEY, "") == sig:
            continue
        if owner.name not in cache:
            me = owner.data
            co = np.empty(len(me.vertices) * 3)
            if me.shape_keys is not None:
                # the shape keys mixed as Blender mixes them (relative to the basis)
                basis = me.shape_keys.reference_key
                basis.data.foreach_get("co", co)
                base = co.reshape(-1, 3).copy()
                mix = base.copy()
                for kb in me.shape_keys.key_blocks:
                    if kb == basis or kb.mute or kb.value == 0.0:
                        continue
                    k = np.empty(len(me.vertices) * 3)
                    kb.data.foreach_get("co", k)
                    rel = kb.relative_key
                    r = np.empty(len(me.vertices) * 3)
                    rel.data.foreach_get("co", r)
                    mix += kb.value * (k.reshape(-1, 3) - r.reshape(-1, 3))
                cache[owner.name] = mix
            else:
                me.vertices.foreach_get("co", co)
                cache[owner.name] = co.reshape(-1, 3)
        X = cache[owner.name]
        t = np.asarray(tri, dtype=np.int64).reshape(-1, 3)
        b = np.asarray(ob.get(LOOP_BARY_KEY), dtype=np.float64).reshape(-1, 3)
        if len(t) == 0 or t.max() >= len(X) or len(ob.data.splines) != 1 or \
                len(ob.data.splines[0].points) != len(t):
            continue
        pts = np.einsum("ik,ikj->ij", b, X[t])
        co4 = np.ones((len(pts), 4))
        co4[:, :3] = pts
        ob.data.splines[0].points.foreach_set("co", co4.ravel())
        ob.data.update_tag()
        ob[LOOP_SIG_KEY] = sig
        moved += 1
    return moved


@bpy.app.handlers.persistent
def _follow_handler(scene, depsgraph=None):
    follow_shape_keys(depsgraph)


def register_handlers():
    for h in (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.frame_change_post):
        if _follow_handler not in h:
            h.append(_follow_handler)


def unregister_handlers():
    for h in (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.frame_change_post):
        while _follow_handler in h:
            h.remove(_follow_handler)
