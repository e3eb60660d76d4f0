"""surfmap: globally optimal maps between closed surfaces of equal genus.

A thin layer over the native module ``_core``. Arrays are numpy: vertices
float64 (n, 3), triangles int32 (m, 3). Every error derives from
``surfmap.Error``: ``InputError`` (also a ValueError) names the offending
element of a bad input, ``SolveError`` (also a RuntimeError) a failed solve,
``UniformizationError`` (a SolveError) a uniformization metric that could not
be delivered, ``Cancelled`` a stop asked for by a progress callback.
"""
from . import _core
from ._core import *  # noqa: F401,F403  (the bound functions and exceptions)
from ._core import Cancelled, Error, InputError, SolveError, UniformizationError  # noqa: F401

__version__ = "0.1.0"

#: Keyword arguments this build's ``surface_map`` accepts (a frozenset of
#: names, e.g. "landmarks", "solve_progress"): test membership here rather
#: than searching docstrings.
capabilities = _core.CAPABILITIES
features = _core.FEATURES


def system_of_loops(V, F, base_vertex=-1, refine=True):
    """System of loops of a closed surface of genus >= 1 (docs/method.md §2.2).

    V: float64 (n, 3), F: int (m, 3). Returns a dict with the refined mesh
    ("V", "F", "origin_face", "origin_barycentric"), "genus", "base_vertex",
    "loops" (2g int arrays [x, ..., x], simple and disjoint except at x when
    refine=True), "generator_edges", "word" (letters +-(k+1)) and "word_text".
    Raises InputError for an invalid mesh or genus 0.
    """
    return _core.system_of_loops(V, F, base_vertex=base_vertex, refine=refine)


def verify(Vs, Fs, Vt, Ft, forward, inverse=None, barycentric_tolerance=1e-9, area_tolerance=0.25,
           inverse_tolerance=1.0, strict=False):
    """Independent certificate that a map Vs/Fs -> Vt/Ft is a bijection (docs/verification.md).

    forward: {'face' (n_s,), 'barycentric' (n_s, 3)} per source vertex, inverse: the same per
    target vertex; or pass surface_map's result dict as `forward` (its 'forward' and 'inverse'
    are used). Shares no code with the solver beyond mesh intake. Returns a dict with
    'certified', 'failures' (one line per failed check), 'undecided' (checks that failed only on
    unresolved images, where the target's normals at an image triangle's corners differ by more than
    60 degrees; failures with strict=True), 'summary' (the printed certificate)
    and the figures of every check ('negative_triangles', 'winding_failures', 'area_ratio',
    'degree', 'max_inverse_error', ...). Raises InputError for unusable meshes or arrays.
    """
    if inverse is None:
        if not (isinstance(forward, dict) and "forward" in forward and "inverse" in forward):
            raise InputError("verify: pass forward and inverse, or a surface_map result")
        forward, inverse = forward["forward"], forward["inverse"]
    return _core.verify(Vs, Fs, Vt, Ft, forward, inverse, barycentric_tolerance=barycentric_tolerance,
                        area_tolerance=area_tolerance, inverse_tolerance=inverse_tolerance, strict=strict)
