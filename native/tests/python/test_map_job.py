"""surfmap.start_surface_map / surfmap.MapJob (docs/python.md "start_surface_map and MapJob"): a closed pair's
solve on a C++ thread that never takes the GIL; progress polled, cancel, result and errors on the
calling thread."""
import sys
import threading
import time

import numpy as np
import pytest

import surfmap
from mesh_helpers import torus


@pytest.fixture(scope="module")
def genus2():
    return surfmap.shapes.n_hole_torus(2, 14, True), surfmap.shapes.vase(18, True)


def _same_map(a, b):
    """The two result dicts describe the same map: energies, class, per-vertex images, distortion."""
    assert set(a) == set(b)
    assert a["energy"] == b["energy"]
    assert a["homotopy"]["chosen"] == b["homotopy"]["chosen"]
    assert (a["source_flipped"], a["target_flipped"]) == (b["source_flipped"], b["target_flipped"])
    for side in ("forward", "inverse"):
        np.testing.assert_array_equal(a[side]["face"], b[side]["face"])
        np.testing.assert_allclose(a[side]["barycentric"], b[side]["barycentric"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(a["distortion"]["per_face"], b["distortion"]["per_face"], rtol=1e-12)


def test_a_polled_job_gives_surface_maps_result(genus2):
    a, b = genus2
    # One pipeline thread: the order of the progress calls is then fixed (two threads overlap
    # stages); the map does not depend on it.
    job = surfmap.start_surface_map(*a, *b, threads=1)
    assert isinstance(job, surfmap.MapJob)
    polls = []
    while not job.done():
        polls.append(job.progress())
        time.sleep(0.002)
    final = job.progress()
    assert final["done"] and not final["cancelled"] and not any(p["done"] for p in polls)
    calls, solve_calls = [], []
    direct = surfmap.surface_map(*a, *b, threads=1, progress=lambda s, f: calls.append((s, f)) or True,
                                 solve_progress=lambda i, e, g: solve_calls.append((i, e, g)) or True)
    # Every stage the polls saw is one surface_map's callback was given, and some were seen while
    # it ran; the last state is the callbacks' last call, stage and the harmonic solve's figures.
    seen = {p["stage"] for p in polls}
    assert seen <= {s for s, _ in calls} | {"starting"} and seen - {"starting"}, seen
    assert all(0.0 <= p["fraction"] <= 1.0 for p in polls)
    assert (final["stage"], final["fraction"]) == calls[-1]
    assert solve_calls and (final["iteration"], final["energy"], final["gradient"]) == solve_calls[-1]
    _same_map(job.result(), direct)
    assert job.wait(0) and job.wait()


def test_wait_timeouts_follow_threading_event_wait(genus2):
    """wait(t): t <= 0 does not wait (it waited until done for a negative t), inf waits until
    done (it returned at once: the deadline overflowed the clock), NaN is refused."""
    a, b = genus2
    job = surfmap.start_surface_map(*a, *b)
    t = time.monotonic()
    assert job.wait(-1.0) is False   # (the intake alone takes longer than this call)
    assert time.monotonic() - t < 0.5
    with pytest.raises(surfmap.InputError, match="NaN"):
        job.wait(float("nan"))
    assert job.wait(float("inf")) is True and job.done()
    assert job.wait(-1.0) is True    # done: returns done() without waiting


def test_genus1_job_with_keywords_gives_the_same_map():
    a, b = torus(1.0, 0.5, 40, 20), torus(1.5, 0.5, 50, 20, 1)
    kw = dict(landmarks=[(0, 7)], method="relaxation", tolerance=1e-8)
    job = surfmap.start_surface_map(*a, *b, **kw)
    _same_map(job.result(), surfmap.surface_map(*a, *b, **kw))


def test_cancel_mid_solve_raises_cancelled(genus2):
    a, b = genus2
    job = surfmap.start_surface_map(*a, *b)
    while job.progress()["iteration"] is None:   # inside a harmonic solve
        assert not job.done(), "the job finished before a harmonic solve was seen"
        time.sleep(0.0005)
    assert job.cancel() is True
    assert job.progress()["cancelled"]
    with pytest.raises(surfmap.Cancelled):
        job.result()
    assert job.done()
    with pytest.raises(surfmap.Cancelled):   # every call says so
        job.result()
    assert job.cancel() is False             # done (cancelled): nothing left to cancel


def test_cancel_follows_future_cancel(genus2):
    """cancel() as concurrent.futures.Future.cancel: False once the job is done, and its result
    stands (it returned None and result() gave the map, against the docstring's Cancelled); True
    while it runs, and then result() raises Cancelled, also for a cancel that comes after the
    solve's last progress point (the map was returned then)."""
    a, b = genus2
    job = surfmap.start_surface_map(*a, *b)
    assert job.wait()
    assert job.cancel() is False
    assert not job.progress()["cancelled"]
    assert job.result()["energy"]["final"] > 0
    # A cancel late in the job (the last stage, or done already): either outcome is consistent.
    late = surfmap.start_surface_map(*a, *b)
    while late.progress()["fraction"] < 0.99 and not late.done():
        time.sleep(0.0005)
    if late.cancel():
        assert late.progress()["cancelled"]
        with pytest.raises(surfmap.Cancelled):
            late.result()
    else:
        assert late.done() and not late.progress()["cancelled"]
        assert late.result()["energy"]["final"] > 0


def test_errors_are_surface_maps(genus2):
    (Vs, Fs), (Vt, Ft) = genus2
    T = torus(1.0, 0.5, 20, 10)
    # Conversion errors at the call, as surface_map raises them.
    for kw, word in ((dict(tolerance=-1.0), "tolerance"), (dict(method="nope"), "method"),
                     (dict(niceness=-1), "niceness")):
        with pytest.raises(surfmap.InputError, match=word):
            surfmap.start_surface_map(Vs, Fs, Vt, Ft, **kw)
    with pytest.raises(TypeError):
        surfmap.start_surface_map(Vs, Fs, Vt, Ft, no_such_keyword=1)
    # No Python on the solve's thread: no callbacks, no open pairs.
    for kw in (dict(progress=lambda s, f: True), dict(solve_progress=lambda i, e, g: True)):
        with pytest.raises(surfmap.InputError, match="no progress callbacks"):
            surfmap.start_surface_map(Vs, Fs, Vt, Ft, **kw)
    disk_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    disk_F = np.array([[0, 1, 2]])
    with pytest.raises(surfmap.InputError, match="closed surfaces only"):
        surfmap.start_surface_map(disk_V, disk_F, disk_V, disk_F)
    # Errors of the intake and the solve: from result(), with surface_map's class and message.
    with pytest.raises(surfmap.InputError) as direct:
        surfmap.surface_map(Vs, Fs, *T)
    job = surfmap.start_surface_map(Vs, Fs, *T)
    with pytest.raises(surfmap.InputError) as from_job:
        job.result()
    assert str(from_job.value) == str(direct.value) and "genus" in str(direct.value)


def test_dropping_a_running_job_stops_it(genus2):
    """A dropped job is cancelled and joined. Its harmonic solves (the ranking's coarse ones
    too) here run to 10^6 iterations (tolerance 1e-300 is never met): uncancelled, the solve
    lasts hours, so only the cancel ends the drop (a destructor that joined without cancelling returned within 30 s on the default
    solve: the old test could not fail). The drop runs on a thread of its own so that a failure
    fails rather than hangs (the interpreter's exit hook cancels the job then)."""
    a, b = genus2
    box = [surfmap.start_surface_map(*a, *b, tolerance=1e-300, max_iterations=10**6)]
    while box[0].progress()["stage"] == "starting":   # (its coarse solves run 10^6 iterations too)
        assert not box[0].done(), box[0].result()
        time.sleep(0.001)
    dropped = threading.Event()

    def drop():
        box.clear()   # the last reference: MapJob's destructor runs here
        dropped.set()

    threading.Thread(target=drop, daemon=True).start()
    assert dropped.wait(120), "dropping the job did not stop its solve"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="per-thread nice is Linux's")
def test_the_solve_thread_lowers_its_own_priority(genus2):
    import os
    a, b = genus2
    here = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    job = surfmap.start_surface_map(*a, *b, niceness=5)
    while job.thread_id == 0:
        time.sleep(0.0005)
    tid, step = job.thread_id, job.niceness
    assert tid != threading.get_native_id()
    assert step == min(5, 19 - here)
    try:
        seen = os.getpriority(os.PRIO_PROCESS, tid)
    except OSError:   # finished already
        seen = None
    job.result()
    if seen is not None:
        assert seen == here + step
    assert os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) == here   # not the caller's
    plain = surfmap.start_surface_map(*a, *b, niceness=0)
    plain.result()
    assert plain.niceness == 0


def _spin_holding_the_gil(until, seconds):
    """Runs Python on this thread without ever releasing the GIL (a switch interval of 1000 s:
    a thread that asks for it waits that long) until `until()` or `seconds` passed; returns
    whether `until()` became true."""
    before = sys.getswitchinterval()
    sys.setswitchinterval(1000.0)
    try:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if until():
                return True
        return False
    finally:
        sys.setswitchinterval(before)


def test_the_solve_thread_never_takes_the_gil(genus2):
    """The add-on's tick test failure (docs/addon.md "The solve's thread"): a niced solve thread that
    asks for the GIL stalls the thread holding it. Here the main thread holds the GIL the whole
    time: the job must still run to its end. The control is the old design, surface_map with a
    progress callback on a Python thread: its first callback waits for the GIL, so it cannot
    finish while the GIL is held (the test would fail for a job that took the GIL)."""
    a, b = genus2
    job = surfmap.start_surface_map(*a, *b)
    assert _spin_holding_the_gil(job.done, 300), "the job did not finish while the GIL was held"
    assert job.result()["energy"]["final"] > 0

    finished = threading.Event()
    calls = []

    def old_design():
        surfmap.surface_map(*a, *b, progress=lambda s, f: calls.append(s) or True)
        finished.set()

    t = threading.Thread(target=old_design)
    t.start()
    time.sleep(0.05)   # (the thread converts its arguments with the GIL: let it start)
    stalled = not _spin_holding_the_gil(finished.is_set, 3.0)
    t.join()
    assert stalled and finished.is_set() and calls


@pytest.mark.parametrize("kw", [dict(threads=1), dict(threads=2), dict(threads=1, source_base_vertex=5)])
def test_progress_fractions_never_decrease(genus2, kw):
    """Review of session 26: the fraction stepped back from 0.42 to 0.40 (the full-resolution
    solves' hook reported the ranking's 0.40 after the ranking's end at 0.42), and a given base
    vertex's run (the automatic cuts' map, then the given cuts') counted from 0 twice. Within a
    run the fractions given to `progress` never decrease and end at 1; a polled job's too."""
    a, b = genus2
    calls = []
    surfmap.surface_map(*a, *b, **kw, progress=lambda s, f: calls.append((s, f)) or True)
    fractions = [f for _, f in calls]
    assert fractions and fractions[-1] == 1.0
    back = [(calls[i], calls[i + 1]) for i in range(len(calls) - 1) if fractions[i + 1] < fractions[i]]
    assert not back, back
    job = surfmap.start_surface_map(*a, *b, **kw)
    polled = []
    while not job.done():
        polled.append(job.progress()["fraction"])
        time.sleep(0.001)
    polled.append(job.progress()["fraction"])
    assert all(y >= x for x, y in zip(polled, polled[1:])), polled
    assert polled[-1] == 1.0
