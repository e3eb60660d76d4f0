"""Runs every test_* function of blender_tests/test_*.py inside Blender.

  blender -b --factory-startup --python-exit-code 1 --python blender_tests/run_all.py [-- -k NAME]

Enables the add-on straight from the repository (<repo>/addon on the add-on search path), runs
each test function on an empty scene, writes {passed, failed, failures} as JSON to
$SURFMAP_TEST_RESULTS when set, prints one summary line 'N passed, M failed' and exits
non-zero when anything failed. The native module is found by the add-on itself (vendored copy,
sys.path, SURFMAP_PYTHONPATH, or <repo>/build/python).
"""
import importlib
import json
import os
import sys
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(REPO, "addon"))

import addon_utils  # noqa: E402
import bpy  # noqa: E402


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    pattern = argv[argv.index("-k") + 1] if "-k" in argv else ""
    mod = addon_utils.enable("surface_map", default_set=True, handle_error=None)
    if mod is None:
        print("FATAL: could not enable the surface_map add-on from", os.path.join(REPO, "addon"))
        out = os.environ.get("SURFMAP_TEST_RESULTS")
        if out:
            with open(out, "w") as f:
                json.dump({"passed": 0, "failed": 1, "failures": ["enable add-on"]}, f)
        print("0 passed, 1 failed")
        sys.exit(1)
    import helpers
    passed, failed, failures = 0, 0, []
    files = sorted(f for f in os.listdir(HERE) if f.startswith("test_") and f.endswith(".py"))
    for fname in files:
        module = importlib.import_module(fname[:-3])
        for name in sorted(n for n in dir(module) if n.startswith("test_")):
            fn = getattr(module, name)
            if not callable(fn) or (pattern and pattern not in f"{fname[:-3]}.{name}"):
                continue
            helpers.reset_scene()
            t0 = time.time()
            try:
                fn()
            except Exception:
                failed += 1
                failures.append(f"{fname[:-3]}.{name}")
                print(f"FAIL {fname[:-3]}.{name} ({time.time() - t0:.1f}s)")
                traceback.print_exc()
            else:
                passed += 1
                print(f"ok   {fname[:-3]}.{name} ({time.time() - t0:.1f}s)")
            sys.stdout.flush()
    if failures:
        print("failed:", ", ".join(failures))
    out = os.environ.get("SURFMAP_TEST_RESULTS")
    if out:  # read by scripts/summarize_tests.py
        with open(out, "w") as f:
            json.dump({"passed": passed, "failed": failed, "failures": failures}, f)
    print(f"{passed} passed, {failed} failed")
    sys.stdout.flush()
    if failed or passed == 0:
        sys.exit(1)


main()
