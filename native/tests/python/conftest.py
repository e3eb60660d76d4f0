"""Puts the built `surfmap` package on sys.path ($SURFMAP_PYTHONPATH, else
<repo>/build/python) and offers the built CLI as a fixture."""
import os
import pathlib
import subprocess
import sys

import pytest

_repo = pathlib.Path(__file__).resolve().parents[3]
_path = pathlib.Path(os.environ.get("SURFMAP_PYTHONPATH") or _repo / "build" / "python")
if str(_path) not in sys.path:
    sys.path.insert(0, str(_path))


@pytest.fixture(scope="session")
def cli():
    """Runs the `surfmap` program: cli("info", path) -> CompletedProcess."""
    exe = pathlib.Path(os.environ.get("SURFMAP_CLI") or _path.parent / "bin" / "surfmap")
    assert exe.exists(), f"surfmap CLI not built at {exe}"

    def run(*args, timeout=600):
        return subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True, timeout=timeout)

    return run
