"""Lazy import of the native `surfmap` package (pybind11 module + thin Python wrapper).

Looked for, in this order, so that nobody has to copy files by hand:
1. the copy vendored inside the add-on (`surface_map/surfmap/`, what the release zip ships);
2. `import surfmap` from the current sys.path;
3. the folders in the SURFMAP_PYTHONPATH environment variable (os.pathsep-separated), the
   folder set in the add-on preferences, and the repository's `build/python` next to the
   add-on source (`<repo>/addon/surface_map/../../build/python`, then `<repo>/build*/python`).
The first failure's text is remembered so the panel can show why the module is missing.
This module does not import bpy.
"""
import glob
import importlib
import os
import sys

_module = None
_error = ""
_origin = ""
_tried = False


def _candidate_dirs(extra_dirs=()):
    dirs = []
    env = os.environ.get("SURFMAP_PYTHONPATH", "")
    dirs += [d for d in env.split(os.pathsep) if d]
    dirs += [d for d in extra_dirs if d]
    repo = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
    dirs.append(os.path.join(repo, "build", "python"))
    # Developer build directories (build-release, build-debug, ...), newest first.
    others = [d for d in glob.glob(os.path.join(repo, "build*", "python"))
              if os.path.isdir(os.path.join(d, "surfmap"))]
    others.sort(key=lambda d: os.path.getmtime(os.path.join(d, "surfmap")), reverse=True)
    dirs += others
    out = []
    for d in dirs:
        d = os.path.abspath(d)
        if d not in out:
            out.append(d)
    return out


def _has_core(mod):
    # A namespace package or a half-built folder imports but has no native core.
    return hasattr(mod, "intake") and hasattr(mod, "Error")


def load(extra_dirs=(), force=False):
    """Returns the surfmap module or None; never raises. See error() for the reason."""
    global _module, _error, _origin, _tried
    if _module is not None and not force:
        return _module
    if _tried and not force:
        return None
    _tried = True
    errors = []
    # 1. vendored copy
    try:
        mod = importlib.import_module(__package__ + ".surfmap") if __package__ else None
        if mod is not None and _has_core(mod):
            _module, _error, _origin = mod, "", os.path.dirname(mod.__file__)
            return _module
        errors.append(f"vendored copy at {getattr(mod, '__path__', '?')} has no native core")
    except ImportError as e:
        if getattr(e, "name", None) not in (f"{__package__}.surfmap",):
            errors.append(f"vendored copy: {e}")
    # 2. sys.path
    try:
        mod = importlib.import_module("surfmap")
        if _has_core(mod):
            _module, _error, _origin = mod, "", os.path.dirname(mod.__file__ or "")
            return _module
        errors.append(f"'surfmap' on sys.path at {getattr(mod, '__path__', '?')} has no native core")
        sys.modules.pop("surfmap", None)
    except ImportError as e:
        if getattr(e, "name", None) != "surfmap":
            errors.append(f"sys.path: {e}")
    # 3. explicit folders
    for d in _candidate_dirs(extra_dirs):
        if not os.path.isdir(os.path.join(d, "surfmap")):
            continue
        sys.path.insert(0, d)
        try:
            for name in [m for m in sys.modules if m == "surfmap" or m.startswith("surfmap.")]:
                del sys.modules[name]
            mod = importlib.import_module("surfmap")
            if _has_core(mod):
                _module, _error, _origin = mod, "", os.path.dirname(mod.__file__)
                return _module
            errors.append(f"{d}: package has no native core")
        except Exception as e:  # a broken .so raises ImportError, OSError, ...
            errors.append(f"{d}: {type(e).__name__}: {e}")
        sys.path.remove(d)
    if not errors:
        errors.append("the surfmap module was not found (build the _core target, or install the "
                      "release zip; searched: " + ", ".join(_candidate_dirs(extra_dirs)) + ")")
    _error = "; ".join(errors)
    return None


def error():
    """Why the last load() failed ("" when loaded)."""
    return _error


def origin():
    """Folder the module was imported from ("" when not loaded)."""
    return _origin


def reset():
    global _module, _error, _origin, _tried
    _module, _error, _origin, _tried = None, "", "", False
