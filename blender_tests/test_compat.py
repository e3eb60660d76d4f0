"""Loading on Blender 3.4 and 4.x: every module of the add-on imports here (3.4) and is listed
in __init__'s module lists (so Reload Scripts and register reach it); no module uses an API
that Blender 4.0-4.2 removed (read from the source, since only 3.4 runs here; the table in
docs/addon.md "Blender 4.x"); blender_manifest.toml passes the checks Blender 4.2's
`blender --command extension validate` makes (the rules as its manual states them)."""
import ast
import importlib
import os
import re
import tomllib

HERE = os.path.dirname(os.path.abspath(__file__))
ADDON = os.path.join(os.path.dirname(HERE), "addon", "surface_map")

# Attributes removed in Blender 4.0-4.2 (Mesh.calc_normals, face maps, edge/vertex crease and
# bevel weight as properties: 4.0; auto smooth and split normals: 4.1) or deprecated with
# removal announced (Mesh.vertex_colors: colour attributes since 3.2).
REMOVED_ATTRIBUTES = {
    "calc_normals": "Mesh.calc_normals (4.0: normals are always up to date)",
    "calc_normals_split": "Mesh.calc_normals_split (4.1: corner_normals)",
    "free_normals_split": "Mesh.free_normals_split (4.1)",
    "create_normals_split": "Mesh.create_normals_split (4.1)",
    "use_auto_smooth": "Mesh.use_auto_smooth (4.1: the Smooth by Angle modifier)",
    "auto_smooth_angle": "Mesh.auto_smooth_angle (4.1)",
    "face_maps": "face maps (4.0: boolean face attributes)",
    "vertex_colors": "Mesh.vertex_colors (color_attributes since 3.2)",
    "bevel_weight": "MeshEdge/MeshVertex.bevel_weight (4.0: attributes)",
    "crease": "MeshEdge.crease (4.0: the attribute 'crease_edge')",
    "tessfaces": "Mesh.tessfaces (2.8)",
}
REMOVED_MODULES = {"bgl": "bgl (4.0: the gpu module)"}
# Built-in shader names Blender 4.x knows (the 2D_/3D_ prefixed ones went in 4.0).
SHADERS_4X = {"UNIFORM_COLOR", "SMOOTH_COLOR", "FLAT_COLOR", "IMAGE", "IMAGE_COLOR",
              "POLYLINE_FLAT_COLOR", "POLYLINE_SMOOTH_COLOR", "POLYLINE_UNIFORM_COLOR",
              "POINT_FLAT_COLOR", "POINT_UNIFORM_COLOR"}
# Principled BSDF inputs renamed in 4.0 (a literal lookup of one raises KeyError there).
RENAMED_BSDF_INPUTS = {"Subsurface", "Subsurface Color", "Specular", "Specular Tint",
                       "Transmission", "Sheen", "Sheen Tint", "Clearcoat",
                       "Clearcoat Roughness", "Clearcoat Normal", "Emission"}


def _modules():
    return sorted(f[:-3] for f in os.listdir(ADDON) if f.endswith(".py") and f != "__init__.py")


def _parse(name):
    with open(os.path.join(ADDON, name + ".py"), encoding="utf-8") as f:
        return ast.parse(f.read(), filename=name + ".py")


def test_every_module_imports_and_is_listed():
    import surface_map
    listed = set(surface_map._BPY_MODULES) | set(surface_map._PLAIN_MODULES)
    missing = [m for m in _modules() if m not in listed]
    assert not missing, f"modules not in __init__'s lists (Reload Scripts skips them): {missing}"
    assert listed <= set(_modules()), listed - set(_modules())
    for m in _modules():
        mod = importlib.import_module(f"surface_map.{m}")
        assert mod.__name__ == f"surface_map.{m}"


def _in_type_error_handler(tree, node):
    """True when `node` lies in an `except TypeError` (or a tuple naming it) handler."""
    for h in ast.walk(tree):
        if isinstance(h, ast.ExceptHandler) and h.type is not None:
            names = [h.type] if not isinstance(h.type, ast.Tuple) else h.type.elts
            if any(isinstance(n, ast.Name) and n.id == "TypeError" for n in names):
                if any(sub is node for b in h.body for sub in ast.walk(b)):
                    return True
    return False


def api_problems(tree, where):
    """The uses of APIs gone in Blender 4.x in one module's syntax tree, as messages."""
    out = []
    for node in ast.walk(tree):
        line = f"{where}:{getattr(node, 'lineno', '?')}"
        if isinstance(node, ast.Attribute) and node.attr in REMOVED_ATTRIBUTES:
            out.append(f"{line}: {REMOVED_ATTRIBUTES[node.attr]}")
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
            out += [f"{line}: {REMOVED_MODULES[n.split('.')[0]]}" for n in names
                    if n.split(".")[0] in REMOVED_MODULES]
        elif isinstance(node, ast.Call):
            fn = node.func
            fname = fn.attr if isinstance(fn, ast.Attribute) else getattr(fn, "id", "")
            literal = [a.value for a in node.args[:1]
                       if isinstance(a, ast.Constant) and isinstance(a.value, str)]
            if fname in ("from_builtin", "_shader") and literal and literal[0] not in SHADERS_4X:
                out.append(f"{line}: built-in shader '{literal[0]}' does not exist in 4.x")
            if (fname == "size" and isinstance(fn, ast.Attribute) and getattr(fn.value, "id", "") == "blf"
                    and len(node.args) >= 3 and not _in_type_error_handler(tree, node)):
                out.append(f"{line}: blf.size(font, size, dpi) (4.0 takes no dpi) outside the "
                           f"TypeError fallback")
        elif isinstance(node, ast.Subscript) and isinstance(node.value, ast.Attribute) \
                and node.value.attr == "inputs" and isinstance(node.slice, ast.Constant) \
                and node.slice.value in RENAMED_BSDF_INPUTS:
            out.append(f"{line}: Principled BSDF input '{node.slice.value}' (renamed in 4.0)")
    return out


def test_no_api_removed_in_blender_4():
    problems = []
    for m in _modules() + ["__init__"]:
        problems += api_problems(_parse(m), f"{m}.py")
    assert not problems, "\n".join(problems)


def test_the_api_check_finds_each_kind_of_removed_use():
    """The check itself, on code that uses each removed API once (and on the allowed forms)."""
    bad = ast.parse("import bgl\nme.calc_normals()\nme.use_auto_smooth = True\n"
                    "me.vertex_colors.new()\ngpu.shader.from_builtin('3D_UNIFORM_COLOR')\n"
                    "blf.size(0, 12, 72)\nbsdf.inputs['Emission'].default_value = c\n")
    kinds = api_problems(bad, "t")
    assert len(kinds) == 7, kinds
    good = ast.parse("gpu.shader.from_builtin('UNIFORM_COLOR')\ntry:\n    blf.size(0, 12)\n"
                     "except TypeError:\n    blf.size(0, 12, 72)\n"
                     "bsdf.inputs['Base Color'].default_value = c\nme.color_attributes.new()\n")
    assert api_problems(good, "t") == []


# --- blender_manifest.toml (Blender 4.2 extensions) --------------------------------------------

ADDON_TAGS = {"3D View", "Add Curve", "Add Mesh", "Animation", "Bake", "Camera", "Compositing",
              "Development", "Game Engine", "Geometry Nodes", "Grease Pencil", "Import-Export",
              "Lighting", "Material", "Modeling", "Mesh", "Node", "Object", "Paint", "Pipeline",
              "Physics", "Render", "Rigging", "Scene", "Sculpt", "Sequencer", "System",
              "Text Editor", "Tracking", "User Interface", "UV"}
PLATFORMS = {"windows-x64", "windows-arm64", "macos-x64", "macos-arm64", "linux-x64"}
PERMISSIONS = {"files", "network", "clipboard", "camera", "microphone"}
REQUIRED = ("schema_version", "id", "version", "name", "tagline", "maintainer", "type",
            "blender_version_min", "license")
KNOWN = set(REQUIRED) | {"blender_version_max", "website", "copyright", "permissions", "tags",
                         "platforms", "wheels", "build"}
SEMVER = re.compile(r"^(0|[1-9]\d*)\.(0|[1-9]\d*)\.(0|[1-9]\d*)(-[0-9A-Za-z.-]+)?(\+[0-9A-Za-z.-]+)?$")


def _terse(text):
    """Blender's rule for a tagline or a permission's reason: at most 64 characters, no
    surrounding white space, ending in a letter, digit or closing bracket."""
    if not text or text != text.strip():
        return "empty or with surrounding white space"
    if len(text) > 64:
        return f"{len(text)} characters (at most 64)"
    if not (text[-1].isalnum() or text[-1] in ")]}"):
        return "ends with punctuation"
    return None


def manifest_problems(m, package_dir_name, bl_info):
    out = [f"missing '{k}'" for k in REQUIRED if k not in m]
    out += [f"unknown key '{k}'" for k in m if k not in KNOWN]
    if out:
        return out
    if m["schema_version"] != "1.0.0":
        out.append(f"schema_version {m['schema_version']!r}")
    if not (m["id"].isidentifier() and not m["id"].startswith("_")) or m["id"] != package_dir_name:
        out.append(f"id {m['id']!r}: an identifier equal to the package folder {package_dir_name!r}")
    if not SEMVER.match(m["version"]):
        out.append(f"version {m['version']!r} is not semantic")
    elif m["version"] != ".".join(str(x) for x in bl_info["version"]):
        out.append(f"version {m['version']} differs from bl_info's {bl_info['version']}")
    if m["type"] != "add-on":
        out.append(f"type {m['type']!r}")
    parts = m["blender_version_min"].split(".")
    if len(parts) != 3 or not all(p.isdigit() for p in parts):
        out.append(f"blender_version_min {m['blender_version_min']!r}: three numbers")
    elif tuple(int(p) for p in parts) < (4, 2, 0):
        out.append("blender_version_min below 4.2.0 (the first version reading a manifest)")
    for k in ("name", "maintainer"):
        if not m[k].strip() or m[k] != m[k].strip():
            out.append(f"{k} {m[k]!r}")
    if (e := _terse(m["tagline"])) is not None:
        out.append(f"tagline: {e}")
    if bl_info.get("description") != m["tagline"]:
        # Blender 3.4-4.1 show bl_info's description in Preferences > Add-ons, cut in the
        # middle past ~70 characters at the window's default width; 4.2+ show the tagline
        out.append(f"tagline {m['tagline']!r} differs from bl_info's description {bl_info.get('description')!r}")
    if not m["license"] or not all(isinstance(x, str) and x.startswith("SPDX:") for x in m["license"]):
        out.append(f"license {m['license']!r}: 'SPDX:' identifiers")
    out += [f"tag {t!r} is not an add-on tag" for t in m.get("tags", []) if t not in ADDON_TAGS]
    out += [f"platform {p!r}" for p in m.get("platforms", []) if p not in PLATFORMS]
    perms = m.get("permissions", {})
    if not isinstance(perms, dict):
        out.append("permissions must be a table of reasons")
    else:
        for k, reason in perms.items():
            if k not in PERMISSIONS:
                out.append(f"permission {k!r}")
            elif not isinstance(reason, str) or (e := _terse(reason)) is not None:
                out.append(f"permission {k!r} reason: {e if isinstance(reason, str) else reason!r}")
    return out


def test_manifest_is_valid_for_blender_4_2():
    import surface_map
    with open(os.path.join(ADDON, "blender_manifest.toml"), "rb") as f:
        m = tomllib.load(f)
    problems = manifest_problems(m, os.path.basename(ADDON), surface_map.bl_info)
    assert not problems, problems
    # the checks reject what Blender rejects
    bad = dict(m, tagline="Maps surfaces.", tags=["Meshes"], version="0.2",
               permissions={"files": "x" * 70, "disk": "reads"})
    found = " | ".join(manifest_problems(bad, os.path.basename(ADDON), surface_map.bl_info))
    for word in ("tagline: ends with punctuation", "tag 'Meshes'", "not semantic",
                 "64", "permission 'disk'", "differs from bl_info's description"):
        assert word in found, (word, found)
