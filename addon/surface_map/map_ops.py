"""Compatibility only: the module names before the add-on was split by what each file does
(docs/addon.md). New code imports ops_map and ops_stored_map. Registers nothing."""
from .ops_map import (SURFMAP_OT_compute_map, GENERATED_UV, OUTPUT_FLAGS, prepare_job,  # noqa
                      read_side, write_outputs, target_uv_name, before_uv_name, _side)
from .ops_stored_map import (SURFMAP_OT_transfer_uvs, SURFMAP_OT_create_morph,  # noqa: F401
                             SURFMAP_OT_paint_distortion, stored_pair)

classes = (SURFMAP_OT_compute_map, SURFMAP_OT_transfer_uvs, SURFMAP_OT_create_morph,
           SURFMAP_OT_paint_distortion)
