"""Many objects (addon/surface_map/batch_operators.py): the active template mapped onto every
other selected mesh, and Compare Selected (table in a text block, objects coloured by D')."""
import bpy
import numpy as np

import helpers
from helpers import run, select

KEY = "surfmap_mean_dilatation_to_active"


def _targets():
    return [helpers.torus("A", 1.5, 0.5, (4, 0, 0)), helpers.torus("B", 2.0, 0.6, (9, 0, 0)),
            helpers.torus("C", 1.2, 0.5, (0, 5, 0))]


def test_map_active_onto_selected():
    t = helpers.torus("Template", 1.0, 0.5)
    helpers.set_loop_uvs(t, "UVMap", helpers.torus_uvs(t, 1.0))
    targets = _targets()
    V, F = helpers.sm().shapes.sphere(2)
    ball = helpers.mesh_object("Ball", V, F, (0, -5, 0))  # genus 0: skipped, the rest go on
    select([t, *targets, ball], t)
    res, err = run("map_onto_selected")
    assert res == {'FINISHED'}, err
    status = bpy.context.scene.surfmap.map_status
    assert "mapped onto 3 of 4 objects" in status, status
    assert "Ball: skipped" in status and "genus" in status
    for ob in targets:
        me = ob.data
        assert me.uv_layers.get("surfmap UVMap") is not None, ob.name
        assert me.shape_keys is not None and len(me.shape_keys.key_blocks) >= 2, ob.name
        d = ob[KEY]
        assert 1.0 <= d < 3.0, (ob.name, d)
        # the morph key of each target is the template's shape (a torus of radii 1, 0.5)
        key = me.shape_keys.key_blocks[-1]
        co = np.empty(len(me.vertices) * 3)
        key.data.foreach_get("co", co)
        P = co.reshape(-1, 3) - np.asarray(ob.location) * 0  # in place: around its own origin
        rho = np.hypot(P[:, 0], P[:, 1])
        assert np.allclose(np.hypot(rho - 1.0, P[:, 2]), 0.5, atol=0.05), ob.name
    assert ball.data.uv_layers.get("surfmap UVMap") is None and KEY not in ball
    # distinct targets give distinct dilatations (each object got its own map)
    assert len({round(ob[KEY], 6) for ob in targets}) == 3


def test_map_onto_selected_refuses_a_lone_object():
    t = helpers.torus("Template", 1.0, 0.5)
    select([t], t)
    res, err = run("map_onto_selected")
    assert res is None and "select the other meshes" in err


def test_compare_selected_table_and_colours():
    ref = helpers.torus("Ref", 1.6, 0.5)
    targets = _targets()
    copy = helpers.torus("RefCopy", 1.6, 0.5, (0, -6, 0))
    copy.scale = (2.0, 2.0, 2.0)
    copy.rotation_euler = (0.4, 0.2, 1.0)
    objs = [ref, *targets, copy]
    select(objs, ref)
    res, err = run("compare_selected", beta=1.0)
    assert res == {'FINISHED'}, err
    text = bpy.data.texts.get("surfmap comparison")
    assert text is not None
    lines = text.as_string().splitlines()
    names = sorted(o.name for o in objs if o != ref)
    order = ["Ref", *names]
    rows = {ln.split()[0]: [float(x) for x in ln.split()[1:]] for ln in lines[3:3 + len(order)]}
    assert list(rows) == order, lines[:8]
    E = np.array([rows[n] for n in order])
    np.testing.assert_array_equal(E, E.T)
    np.testing.assert_array_equal(np.diag(E), 0)
    k = order.index("RefCopy")
    assert int(np.argsort(E[0])[1]) == k  # the scaled, rotated copy is the nearest
    assert E[0, k] < 1e-3 * min(E[0, j] for j in range(1, len(order)) if j != k)
    assert ref[KEY] == 1.0
    colours = {tuple(round(c, 4) for c in o.color) for o in objs}
    assert len(colours) >= 3  # coloured by D': different objects, different colours
    for o in targets:
        assert o[KEY] > 1.0
