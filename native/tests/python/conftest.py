"""Puts the built `surfmap` package on sys.path: $SURFMAP_PYTHONPATH, else <repo>/build/python."""
import os
import pathlib
import sys

_repo = pathlib.Path(__file__).resolve().parents[3]
_path = os.environ.get("SURFMAP_PYTHONPATH") or str(_repo / "build" / "python")
if _path not in sys.path:
    sys.path.insert(0, _path)
