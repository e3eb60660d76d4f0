"""Compatibility only: the module names before the add-on was split by what each file does
(docs/addon.md). New code imports map_job (and morph for morph_matrix)."""
from .map_job import *  # noqa: F401,F403
from .map_job import MapJob, MapOptions, compute_outputs, corner_uvs  # noqa: F401
from .morph import morph_matrix  # noqa: F401
