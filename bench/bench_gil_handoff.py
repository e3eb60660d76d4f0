"""The main thread's pauses while a map is solved beside it on a niced thread, under CPU load:
the old design (surface_map with progress callbacks on a Python thread niced by 10, as the
add-on ran it until session 25) against the new (start_surface_map: the core's own thread niced
by 10 runs no Python, polled by a worker at normal priority). docs/addon.md "The solve's thread".

  SURFMAP_PYTHONPATH=build/python python3 bench/bench_gil_handoff.py [--burners N]
      [--seconds S] [--designs old new] [--rounds R] [--work-ms W] [--switch-interval I]

For each design and round: N busy processes at nice 0 (the load; stopped after), one worker
thread that maps the genus-2 pair (n-hole torus -> vase) over and over for S seconds, and the
main thread ticking as Blender's timer does (W ms of Python, then a 0.02 s sleep; the switch
interval I, 0.0005 s as the add-on sets it during a job). Prints per
run: solves finished, ticks, the longest pause between two ticks, the 99th percentile, pauses
over 0.5 s, and the load average. Linux only (per-thread nice).
"""
import argparse
import os
import pathlib
import subprocess
import sys
import threading
import time

_repo = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, os.environ.get("SURFMAP_PYTHONPATH") or str(_repo / "build" / "python"))
import numpy as np  # noqa: E402
import surfmap  # noqa: E402

NICENESS = 10


def old_design(pair, stop, solved):
    """surface_map on this thread, niced, with Python callbacks (the add-on before session 26)."""
    tid = threading.get_native_id()
    os.setpriority(os.PRIO_PROCESS, tid, min(os.getpriority(os.PRIO_PROCESS, tid) + NICENESS, 19))
    while not stop.is_set():
        surfmap.surface_map(*pair[0], *pair[1], progress=lambda s, f: True,
                            solve_progress=lambda i, e, g: True)
        solved.append(time.time())


def new_design(pair, stop, solved):
    """start_surface_map polled from this thread at normal priority (the add-on's worker)."""
    while not stop.is_set():
        job = surfmap.start_surface_map(*pair[0], *pair[1], niceness=NICENESS)
        while not job.wait(0.05):
            job.progress()
        job.result()
        solved.append(time.time())


def python_work(ms):
    """About `ms` milliseconds of Python holding the GIL (a timer's or a panel draw's)."""
    end = time.perf_counter() + ms / 1000.0
    while time.perf_counter() < end:
        sum(range(200))


def one_run(design, pair, burners, seconds, work_ms):
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(burners)]
    try:
        time.sleep(1.0)
        stop, solved, ticks = threading.Event(), [], []
        worker = threading.Thread(target={"old": old_design, "new": new_design}[design],
                                  args=(pair, stop, solved), daemon=True)
        worker.start()
        end = time.time() + seconds
        while time.time() < end:
            ticks.append(time.time())
            python_work(work_ms)
            time.sleep(0.02)
        stop.set()
        load = os.getloadavg()[0]
        worker.join()
    finally:
        for p in procs:
            p.kill()
            p.wait()
    gaps = np.diff(ticks)
    return dict(solves=len(solved), ticks=len(ticks), longest=float(gaps.max()),
                p99=float(np.percentile(gaps, 99)), over=int((gaps > 0.5).sum()), load=load)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--burners", type=int, default=4)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--designs", nargs="+", default=["old", "new"], choices=["old", "new"])
    ap.add_argument("--work-ms", type=float, default=1.0)
    ap.add_argument("--switch-interval", type=float, default=0.0005)
    a = ap.parse_args()
    sys.setswitchinterval(a.switch_interval)
    pair = surfmap.shapes.n_hole_torus(2, 24, True), surfmap.shapes.vase(28, True)
    print(f"main thread nice {os.getpriority(os.PRIO_PROCESS, threading.get_native_id())}, "
          f"{a.burners} busy processes at nice 0, {a.seconds:.0f} s per run, {a.work_ms} ms of "
          f"Python per tick, switch interval {a.switch_interval} s")
    for r in range(a.rounds):
        for design in a.designs:
            m = one_run(design, pair, a.burners, a.seconds, a.work_ms)
            print(f"round {r} {design}: {m['solves']} solves, {m['ticks']} ticks, longest pause "
                  f"{m['longest']:.3f} s, p99 {m['p99']:.3f} s, {m['over']} pauses > 0.5 s, "
                  f"load {m['load']:.1f}", flush=True)


if __name__ == "__main__":
    main()
