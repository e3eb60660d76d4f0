#!/usr/bin/env bash
# Builds the Blender add-on zip (<build>/surface_map.zip, the surfmap module vendored inside)
# and installs + enables it in the user's Blender, saving the preferences.
#   scripts/install_addon.sh            # build in $SURFMAP_BUILD_DIR (default <repo>/build)
#   BLENDER=/path/to/blender scripts/install_addon.sh
# Honours BLENDER_USER_CONFIG / BLENDER_USER_SCRIPTS like Blender itself (handy for a
# throw-away install: point both at a temporary folder).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${SURFMAP_BUILD_DIR:-$repo/build}"
blender="${BLENDER:-blender}"
cmake -S "$repo" -B "$build" -DCMAKE_BUILD_TYPE="${SURFMAP_BUILD_TYPE:-Release}" \
  -DPython_EXECUTABLE=/usr/bin/python3 >/dev/null
cmake --build "$build" -j"${SURFMAP_JOBS:-2}" --target addon_zip
zip="$build/surface_map.zip"
[ -f "$zip" ] || { echo "surfmap: $zip was not built" >&2; exit 1; }
SURFMAP_ZIP="$zip" "$blender" -b --factory-startup --python-exit-code 1 --python-expr '
import os, sys, bpy, addon_utils
zip_path = os.environ["SURFMAP_ZIP"]
bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True)
addon_utils.modules_refresh()
mod = addon_utils.enable("surface_map", default_set=True, handle_error=None)
if mod is None:
    print("surfmap: installing worked but enabling the add-on failed"); sys.exit(1)
from surface_map import native
if native.load() is None:
    print("surfmap: add-on enabled but its native module does not load:", native.error()); sys.exit(1)
bpy.ops.wm.save_userpref()
print("surfmap: installed", mod.__file__, "with the native module from", native.origin())
'
