"""One handle class solved on a refined source (bench/refined_source.py; docs/handle_classes.md
"Quality signal"): the class carried to the refined source's cuts through the identity onto the
unrefined source, and the discrete energy converging from above as the source is refined."""
import pathlib
import sys

import numpy as np

import surfmap

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3] / "bench"))
import refined_source  # noqa: E402


def mesh(VF):
    return np.asarray(VF[0], float), np.asarray(VF[1], np.int64)


def ratio_on(source, target, words):
    m = surfmap.surface_map(*source, *target, class_words=words)
    assert m["converged"] and m["flipped_triangles"] == 0
    return m


def test_substitute_composes_words_and_reduces():
    outer = [[1, 2], [-1], [3], [4]]
    assert refined_source.substitute(outer, [[1], [2, -2], [-1, 3], [2, 1]]) == [[1, 2], [], [-2, -1, 3], [2]]
    assert refined_source.free_reduce([1, 2, -2, -1, 3]) == [3]


def test_coarse_cad_block_self_map_falls_toward_the_conformal_bound_when_refined():
    # The generated thick CAD plate g2 (268 vertices, fans of long triangles): its self-map in the
    # identity class costs its own discretisation (1.17 x the bound); on the same surface refined
    # once and twice the identity's energy falls toward the bound (1.050, 1.018), never below it.
    S = mesh(surfmap.shapes.cad_plate(2, thickness=1.0))
    assert refined_source.identity_words(S, S, S[0]) == [[1], [2], [3], [4]]
    identity = [[1], [2], [3], [4]]
    ratios = [ratio_on(S, S, identity)["quality"]["energy_ratio"]]
    R, words = S, identity
    for _ in range(2):
        before, R = R, refined_source.bench_open_surfaces.subdivide(*R)
        words = refined_source.words_on_refined(identity, S, before, words, R)
        ratios.append(ratio_on(R, S, words)["quality"]["energy_ratio"])
    assert ratios[0] > 1.05
    for coarse, fine in zip(ratios, ratios[1:]):
        assert 1 - 1e-9 <= fine < coarse
        assert fine - 1 < 0.5 * (coarse - 1)  # second order in the edge length: about a quarter
    # the words of the unrefined cuts, read in the refined cuts, name another class
    wrong = ratio_on(R, S, [[1], [2], [3], [4]])["quality"]["energy_ratio"]
    assert wrong > 2 * ratios[-1]


def test_a_twisted_class_on_the_refined_source_is_the_same_map():
    # A class far from conformal (the plate onto an amphora, the ranking's first candidate):
    # solved on the refined plate it keeps its map (the input vertices' images move by a small
    # fraction of the target's size) and its energy falls by the plate's discretisation.
    S = mesh(surfmap.shapes.cad_plate(2, thickness=1.0))
    T = mesh(surfmap.shapes.amphora(36))
    m0 = surfmap.surface_map(*S, *T, homotopy=0)
    words = m0["homotopy"]["chosen_words"]
    R = refined_source.bench_open_surfaces.subdivide(*S)
    m1 = ratio_on(R, T, refined_source.words_on_refined(words, S, S, words, R))
    r0, r1 = m0["quality"]["energy_ratio"], m1["quality"]["energy_ratio"]
    assert 1 <= r1 < r0
    diag = np.linalg.norm(T[0].max(axis=0) - T[0].min(axis=0))
    drift = np.linalg.norm(np.asarray(m1["forward"]["position"])[:len(S[0])] - np.asarray(m0["forward"]["position"]),
                           axis=1) / diag
    assert drift.mean() < 0.05
    # the unrefined cuts' words on the refined source: another class, another map (0.23 here)
    m2 = ratio_on(R, T, words)
    moved = np.linalg.norm(np.asarray(m2["forward"]["position"])[:len(S[0])] - np.asarray(m0["forward"]["position"]),
                           axis=1) / diag
    assert moved.mean() > 0.1
