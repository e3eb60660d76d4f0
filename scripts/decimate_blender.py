"""Decimate a closed triangle mesh to about N vertices with Blender's Decimate
modifier (collapse), headless:

    blender -b --factory-startup -P scripts/decimate_blender.py -- IN.{obj,off} OUT.obj N

Reads OBJ or OFF (triangles), writes OBJ with the same orientation. Used for
the "ugly" genus-0 set of docs/robustness.md (coarse decimated models).
"""
import sys

import bmesh
import bpy


def read_mesh(path):
    verts, faces = [], []
    with open(path) as f:
        if path.lower().endswith(".off"):
            tokens = [line.split("#")[0].split() for line in f]
            tokens = [t for t in tokens if t]
            head = tokens[0]
            start = 1
            if head[0].upper() == "OFF" and len(head) == 1:
                nv, nf = int(tokens[1][0]), int(tokens[1][1])
                start = 2
            else:
                nv, nf = int(head[1]), int(head[2])
            for t in tokens[start:start + nv]:
                verts.append(tuple(float(x) for x in t[:3]))
            for t in tokens[start + nv:start + nv + nf]:
                faces.append(tuple(int(x) for x in t[1:1 + int(t[0])]))
        else:
            for line in f:
                p = line.split()
                if not p:
                    continue
                if p[0] == "v":
                    verts.append(tuple(float(x) for x in p[1:4]))
                elif p[0] == "f":
                    faces.append(tuple(int(x.split("/")[0]) - 1 for x in p[1:]))
    return verts, faces


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    src, dst, target = argv[0], argv[1], int(argv[2])
    verts, faces = read_mesh(src)
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    mesh = bpy.data.meshes.new("m")
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    obj = bpy.data.objects.new("m", mesh)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    # A closed triangle mesh of genus 0 has F = 2V - 4 faces.
    ratio = min(1.0, (2 * target - 4) / len(faces))
    mod = obj.modifiers.new("dec", "DECIMATE")
    mod.decimate_type = "COLLAPSE"
    mod.ratio = ratio
    mod.use_collapse_triangulate = True
    bpy.ops.object.modifier_apply(modifier=mod.name)
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bmesh.ops.triangulate(bm, faces=bm.faces[:])
    bm.verts.ensure_lookup_table()
    index = {v: i for i, v in enumerate(bm.verts)}
    with open(dst, "w") as f:
        for v in bm.verts:
            f.write("v %.17g %.17g %.17g\n" % tuple(v.co))
        for face in bm.faces:
            f.write("f %s\n" % " ".join(str(index[v] + 1) for v in face.verts))
    print("decimated %s: %d -> %d vertices, %d faces" % (src, len(verts), len(bm.verts), len(bm.faces)))


main()
