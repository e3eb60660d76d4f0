"""The bpy half of the data path: reading an object's mesh and writing results into the scene
(seams, loop curves in a collection, pair-coloured materials). No algorithms here."""
import bpy
import numpy as np

from . import core

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
        if "Emission" in bsdf.inputs:
            bsdf.inputs["Emission"].default_value = rgba
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


def add_loop_curves(scene, obj, curves, bevel):
    """One cyclic poly curve object per loop, named '<object> a1', ..., points in the
    object's local space and parented to it (so they follow its transform)."""
    remove_loop_curves(obj.name)
    coll = loops_collection(scene, obj)
    made = []
    for name, pts in curves:
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
        k = int(name[1:]) * 2 - 2 + (0 if name[0] == "a" else 1)
        cu.materials.append(loop_material(name, core.pair_colour(k)))
        ob = bpy.data.objects.new(f"{obj.name} {name}", cu)
        ob[OWNER_KEY] = obj.name
        coll.objects.link(ob)
        ob.parent = obj
        ob.matrix_parent_inverse.identity()
        ob.matrix_basis.identity()
        made.append(ob)
    return made
