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

#: Keyword arguments this build's ``surface_map`` accepts (a frozenset of
#: names, e.g. "landmarks", "solve_progress"): test membership here rather
#: than searching docstrings.
capabilities = _core.CAPABILITIES


def system_of_loops(V, F, base_vertex=-1, refine=True):
    """System of loops of a closed surface of genus >= 1 (paper §IV-A).

    V: float64 (n, 3), F: int (m, 3). Returns a dict with the refined mesh
    ("V", "F", "origin_face", "origin_barycentric"), "genus", "base_vertex",
    "loops" (2g int arrays [x, ..., x], simple and disjoint except at x when
    refine=True), "generator_edges", "word" (letters +-(k+1)) and "word_text".
    Raises InputError for an invalid mesh or genus 0.
    """
    return _core.system_of_loops(V, F, base_vertex=base_vertex, refine=refine)
