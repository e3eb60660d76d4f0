"""Compatibility only: the module names before the add-on was split by what each file does
(docs/addon.md). New code imports ops_common and ops_cut_loops. Registers nothing."""
from .ops_common import native_and_object_mode, pick_objects, surfmap_module  # noqa: F401
from .ops_cut_loops import SURFMAP_OT_show_cut_loops  # noqa: F401

classes = (SURFMAP_OT_show_cut_loops,)
