"""surfmap: globally optimal maps between closed surfaces of equal genus.

A thin layer over the native module ``_core``. Arrays are numpy: vertices
float64 (n, 3), triangles int32 (m, 3). Every error derives from
``surfmap.Error``: ``InputError`` (also a ValueError) names the offending
element of a bad input, ``SolveError`` (also a RuntimeError) a failed solve,
``Cancelled`` a stop asked for by a progress callback.
"""
from . import _core
from ._core import *  # noqa: F401,F403  (the bound functions and exceptions)
from ._core import Cancelled, Error, InputError, SolveError  # noqa: F401

__version__ = "0.1.0"
