"""Compatibility only: the module names before the add-on was split by what each file does
(docs/addon.md). Code written against them keeps working; new code imports cut_loops."""
from .cut_loops import *  # noqa: F401,F403
from .cut_loops import ObjectProblem, bounding_diagonal  # noqa: F401
