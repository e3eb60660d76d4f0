"""The installable add-on zip (cmake target addon_zip): its contents, and an install into a
throw-away Blender user folder followed by a map computed with the vendored native module only
(no SURFMAP_PYTHONPATH, no repository on the path)."""
import os
import pathlib
import shutil
import subprocess
import zipfile

import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]
BUILD = pathlib.Path(os.environ.get("SURFMAP_PYTHONPATH") or REPO / "build" / "python").resolve().parent
ZIP = BUILD / "surface_map.zip"


def test_zip_holds_the_addon_and_the_native_module():
    assert ZIP.exists(), f"{ZIP} not built (cmake --build build --target addon_zip)"
    names = set(zipfile.ZipFile(ZIP).namelist())
    for py in (REPO / "addon" / "surface_map").glob("*.py"):
        assert f"surface_map/{py.name}" in names, py.name
    assert "surface_map/blender_manifest.toml" in names
    assert "surface_map/surfmap/__init__.py" in names
    assert any(n.startswith("surface_map/surfmap/_core") and n.endswith(".so") for n in names)


SCRIPT = r'''
import sys, bpy, addon_utils, numpy as np
mod = addon_utils.enable("surface_map", default_set=True, handle_error=None)
assert mod is not None, "not enabled"
from surface_map import native
sm = native.load()
assert sm is not None, native.error()
print("ORIGIN", native.origin())
print("ADDON", mod.__file__)
def torus(name, R, x):
    V, F = sm.shapes.torus_of_revolution(R, 0.5, 32, 16)
    me = bpy.data.meshes.new(name); me.from_pydata(V.tolist(), [], F.tolist()); me.update()
    ob = bpy.data.objects.new(name, me); ob.location.x = x
    bpy.context.scene.collection.objects.link(ob); return ob
a, b = torus("A", 1.0, -3), torus("B", 1.5, 3)
me = a.data; me.uv_layers.new(name="UVMap")
for o in bpy.context.view_layer.objects: o.select_set(o in (a, b))
bpy.context.view_layer.objects.active = b
print("RESULT", bpy.ops.surfmap.compute_map())
print("KEYS", [k.name for k in a.data.shape_keys.key_blocks])
'''


@pytest.mark.skipif(shutil.which("blender") is None, reason="blender is not installed")
def test_zip_installs_and_maps_in_a_fresh_blender(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "SURFMAP_PYTHONPATH"}
    env["BLENDER_USER_CONFIG"] = str(tmp_path / "config")
    env["BLENDER_USER_SCRIPTS"] = str(tmp_path / "scripts")
    expr = ("import bpy; bpy.ops.preferences.addon_install(filepath=%r, overwrite=True); "
            "bpy.ops.preferences.addon_enable(module='surface_map'); "
            "bpy.ops.wm.save_userpref()" % str(ZIP))
    r = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1",
                        "--python-expr", expr], env=env, capture_output=True, text=True,
                       timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    installed = tmp_path / "scripts" / "addons" / "surface_map"
    assert (installed / "surfmap").is_dir() and (installed / "ops_map.py").exists()
    script = tmp_path / "run.py"
    script.write_text(SCRIPT)
    r = subprocess.run(["blender", "-b", "--python-exit-code", "1", "--python", str(script)],
                       env=env, capture_output=True, text=True, timeout=300, cwd=tmp_path)
    out = r.stdout
    assert r.returncode == 0, out[-3000:] + r.stderr[-2000:]
    origin = next(l for l in out.splitlines() if l.startswith("ORIGIN")).split(None, 1)[1]
    assert pathlib.Path(origin).resolve() == (installed / "surfmap").resolve(), origin
    assert "RESULT {'FINISHED'}" in out, out[-3000:]
    assert "surfmap to B" in out
