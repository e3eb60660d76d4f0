"""surfmap batch: many map jobs (one template onto many shapes, many shapes onto a domain, all
pairs, or a JSON list) as tasks on a Dask distributed cluster, resumable, with a summary table
and, for the domain and pairs modes, the comparison table of surfmap.compare.
See docs/many_shapes.md.

Each task reads its two meshes (by path: on several machines the paths must name the same
files everywhere, e.g. a shared folder), runs the native map (the GIL is released during the
solve) and writes into OUT/jobs/<id>/: morph.obj (the source's connectivity at its image on
the target, in the target's coordinates), fields.npz (λ and H of the source on the target's
vertices, for the comparison) and report.json, last. Every file is written to a temporary
name and renamed, so a job whose report.json exists is finished: a re-run skips it. A failed
job writes error.json instead (and is tried again on a re-run); it does not stop the others.
"""
import argparse
import csv
import json
import os
import sys
import time
import traceback

import numpy as np

from . import _core

# The package's parent folder: worker processes started here get it on PYTHONPATH.
_PACKAGE_PARENT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


# ---- jobs ----------------------------------------------------------------------------------


def _job_id(k, source, target):
    def stem(p):
        return os.path.splitext(os.path.basename(p))[0]
    return f"{k:04d}_{stem(source)}__{stem(target)}"


def make_jobs(mode, paths):
    """mode 'template': paths[0] onto each of paths[1:]; 'domain': each of paths[1:] onto
    paths[0]; 'pairs': paths[i] onto paths[j] for i < j. Returns [{"id", "source", "target"}]."""
    if mode == "template":
        pairs = [(paths[0], p) for p in paths[1:]]
    elif mode == "domain":
        pairs = [(p, paths[0]) for p in paths[1:]]
    elif mode == "pairs":
        pairs = [(paths[i], paths[j]) for i in range(len(paths)) for j in range(i + 1, len(paths))]
    else:
        raise _core.InputError(f"unknown batch mode {mode!r}")
    return [{"id": _job_id(k, s, t), "source": s, "target": t} for k, (s, t) in enumerate(pairs)]


def read_jobs(path):
    """A JSON list of {"source", "target"[, "id"]} objects."""
    with open(path) as f:
        items = json.load(f)
    if not isinstance(items, list):
        raise _core.InputError(f"{path}: expected a JSON list of jobs")
    jobs = []
    for k, it in enumerate(items):
        if not isinstance(it, dict) or "source" not in it or "target" not in it:
            raise _core.InputError(f"{path}: job {k} needs 'source' and 'target'")
        jobs.append({"id": str(it.get("id") or _job_id(k, it["source"], it["target"])),
                     "source": it["source"], "target": it["target"]})
    ids = [j["id"] for j in jobs]
    if len(set(ids)) != len(ids):
        raise _core.InputError(f"{path}: job ids are not unique")
    return jobs


def _write_atomic(path, write, mode="w"):
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, mode) as f:
        write(f)
    os.replace(tmp, path)


def run_job(job, out_dir, map_options=None):
    """Runs one job (in a worker or here) unless its report.json exists. Returns
    {"id", "status": "done"|"skipped"|"failed", "report" or "error"}; never raises."""
    from . import compare as C

    folder = os.path.join(out_dir, "jobs", job["id"])
    report_path = os.path.join(folder, "report.json")
    if os.path.exists(report_path):
        with open(report_path) as f:
            return {"id": job["id"], "status": "skipped", "report": json.load(f)}
    os.makedirs(folder, exist_ok=True)
    start = time.time()
    try:
        Vs, Fs = C.load_shape(job["source"])
        Vt, Ft = C.load_shape(job["target"])
        m = C.map_normalised(Vs, Fs, Vt, Ft, map_options)
        face, bary, pos = C.inverse_points(m)
        lam, H = C.pulled_back_fields(Vs, Fs, Vt, Ft, face, bary, pos)
        fface, fbary, _ = C.forward_points(m)
        morph = np.einsum("ik,ikj->ij", fbary, Vt[Ft[fface]])  # on the target as given
        _core.write_obj(os.path.join(folder, "morph.obj"), morph, Fs)
        _write_atomic(os.path.join(folder, "fields.npz"),
                      lambda f: np.savez(f, **{"lambda": lam, "H": H}), mode="wb")
        report = dict(C.map_report(m), id=job["id"], source=job["source"], target=job["target"],
                      wall_time_s=time.time() - start)
        _write_atomic(report_path, lambda f: json.dump(report, f, indent=2))
        err = os.path.join(folder, "error.json")
        if os.path.exists(err):
            os.remove(err)
        return {"id": job["id"], "status": "done", "report": report}
    except Exception as e:  # recorded, never propagated: one bad job does not stop the others
        error = {"id": job["id"], "source": job["source"], "target": job["target"],
                 "error": f"{type(e).__name__}: {e}", "traceback": traceback.format_exc()}
        _write_atomic(os.path.join(folder, "error.json"), lambda f: json.dump(error, f, indent=2))
        return {"id": job["id"], "status": "failed", "error": error["error"]}


# ---- running ------------------------------------------------------------------------------


class ProgressBar:
    """'[#####.....] 7/12 done, 1 failed, 4 skipped' on stderr (one line per update when
    stderr is not a terminal)."""

    def __init__(self, total, stream=sys.stderr, width=30, quiet=False):
        self.total, self.stream, self.width, self.quiet = total, stream, width, quiet
        self.counts = {"done": 0, "failed": 0, "skipped": 0}
        self.tty = hasattr(stream, "isatty") and stream.isatty()

    def update(self, result):
        self.counts[result["status"]] += 1
        if self.quiet:
            return
        n = sum(self.counts.values())
        filled = int(self.width * n / max(self.total, 1))
        line = (f"[{'#' * filled}{'.' * (self.width - filled)}] {n}/{self.total} "
                f"done {self.counts['done']}, failed {self.counts['failed']}, "
                f"skipped {self.counts['skipped']}  {result['id']}")
        self.stream.write(("\r" + line) if self.tty else line + "\n")
        if self.tty and n == self.total:
            self.stream.write("\n")
        self.stream.flush()


def _ensure_worker_path():
    """Worker processes of a LocalCluster are new interpreters: they find the package
    through PYTHONPATH."""
    parts = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    if _PACKAGE_PARENT not in parts:
        os.environ["PYTHONPATH"] = os.pathsep.join([_PACKAGE_PARENT, *parts])


def run_jobs(jobs, out_dir, map_options=None, scheduler=None, workers=2, threads_per_worker=1,
             client=None, quiet=False):
    """Runs the jobs on a Dask cluster: `client` if given, else the scheduler at `scheduler`
    (an address such as tcp://host:8786), else a LocalCluster of `workers` processes.
    Already finished jobs are skipped without being sent. Returns the results in job order."""
    os.makedirs(out_dir, exist_ok=True)
    bar = ProgressBar(len(jobs), quiet=quiet)
    results = {}
    todo = []
    for job in jobs:
        if os.path.exists(os.path.join(out_dir, "jobs", job["id"], "report.json")):
            results[job["id"]] = run_job(job, out_dir)  # reads the report back
            bar.update(results[job["id"]])
        else:
            todo.append(job)
    if todo:
        from distributed import Client, LocalCluster, as_completed

        own_cluster = own_client = None
        try:
            if client is None:
                if scheduler:
                    client = own_client = Client(scheduler)
                else:
                    _ensure_worker_path()
                    own_cluster = LocalCluster(n_workers=workers, threads_per_worker=threads_per_worker,
                                               processes=True, dashboard_address=None)
                    client = own_client = Client(own_cluster)
            out_abs = os.path.abspath(out_dir)
            futures = [client.submit(run_job, job, out_abs, map_options, key=f"surfmap-{job['id']}",
                                     pure=False, retries=1) for job in todo]
            for fut in as_completed(futures):
                job_id = fut.key[len("surfmap-"):]
                try:
                    r = fut.result()
                except Exception as e:  # the worker died twice under this job
                    r = {"id": job_id, "status": "failed", "error": f"{type(e).__name__}: {e}"}
                results[r["id"]] = r
                bar.update(r)
        finally:
            if own_client is not None:
                own_client.close()
            if own_cluster is not None:
                own_cluster.close()
    return [results[j["id"]] for j in jobs]


def run_serial(jobs, out_dir, map_options=None, quiet=True):
    """The same jobs one by one in this process (the reference for the cluster runs)."""
    bar = ProgressBar(len(jobs), quiet=quiet)
    out = []
    for job in jobs:
        out.append(run_job(job, out_dir, map_options))
        bar.update(out[-1])
    return out


SUMMARY_COLUMNS = ["id", "source", "target", "status", "energy", "mean_dilatation", "max_dilatation",
                   "flipped_triangles", "homotopy_chosen", "time_s", "error"]


def write_summary(out_dir, jobs, results):
    rows = []
    for job, r in zip(jobs, results):
        rep = r.get("report") or {}
        rows.append({
            "id": job["id"], "source": job["source"], "target": job["target"],
            "status": "done" if r["status"] == "skipped" else r["status"],
            "energy": rep.get("energy", {}).get("final", ""),
            "mean_dilatation": rep.get("distortion", {}).get("mean", ""),
            "max_dilatation": rep.get("distortion", {}).get("max", ""),
            "flipped_triangles": rep.get("flipped_triangles", ""),
            "homotopy_chosen": rep.get("homotopy", {}).get("chosen", ""),
            "time_s": rep.get("time_s", ""), "error": r.get("error", ""),
        })

    def w(f):
        out = csv.DictWriter(f, fieldnames=SUMMARY_COLUMNS)
        out.writeheader()
        out.writerows(rows)
    _write_atomic(os.path.join(out_dir, "summary.csv"), w)
    _write_atomic(os.path.join(out_dir, "summary.json"), lambda f: json.dump(rows, f, indent=2))
    return rows


def comparison_table(mode, paths, jobs, results, out_dir, beta=1.0, plot_path=None, symmetries=True):
    """The surfmap.compare table from the jobs' fields.npz (mode 'domain' or 'pairs');
    written as OUT/table.csv, table.json and the plot. Returns the matrix, or None when a job
    failed (the table needs every map)."""
    from . import compare as C

    if any(r["status"] == "failed" for r in results):
        return None

    def fields(job):
        with np.load(os.path.join(out_dir, "jobs", job["id"], "fields.npz")) as z:
            return z["lambda"], z["H"]

    reports = [r["report"] for r in results]
    if mode == "domain":
        shapes = paths[1:]
        Vd, Fd = C.load_shape(paths[0])
        syms = C.domain_symmetries(Vd, Fd) if symmetries else None
        E = C.distance_matrix([fields(j) for j in jobs], Vd, Fd, beta, syms)
    else:
        shapes = paths
        n = len(paths)
        E = np.zeros((n, n))
        k = 0
        for i in range(n):
            for j in range(i + 1, n):
                lam, H = fields(jobs[k])
                Vj, Fj = C.load_shape(paths[j])
                E[i, j] = E[j, i] = C.field_distance(lam, H, np.zeros_like(lam), C.mean_curvature(Vj, Fj),
                                                     C.domain_weights(Vj, Fj), beta)
                k += 1
    names = [C.shape_name(s, k) for k, s in enumerate(shapes)]
    result = {"names": names, "matrix": E, "mode": "domain" if mode == "domain" else "direct",
              "beta": beta, "reports": reports}
    C.write_csv(os.path.join(out_dir, "table.csv"), names, E)
    C.write_json(os.path.join(out_dir, "table.json"), result, {"shapes": list(shapes)})
    if plot_path:
        C.plot(plot_path, names, E)
    return E


def main(argv=None):
    p = argparse.ArgumentParser(
        prog="surfmap batch",
        description="Many map jobs on a Dask cluster (a LocalCluster here by default), resumable.")
    p.add_argument("mode", choices=["template", "domain", "pairs", "jobs"],
                   help="template T S...: T onto each S; domain D S...: each S onto D; pairs S...: every "
                        "pair; jobs JOBS.json: a list of {source, target[, id]}")
    p.add_argument("paths", nargs="+", metavar="PATH")
    p.add_argument("--out", required=True, help="output folder (jobs/<id>/, summary.csv, table.csv)")
    p.add_argument("--scheduler", help="address of a running Dask scheduler (default: a LocalCluster)")
    p.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes (default 2)")
    p.add_argument("--threads-per-worker", type=int, default=1)
    p.add_argument("--map-option", action="append", metavar="KEY=VALUE",
                   help="option of the native map (e.g. homotopy_search=false); repeatable")
    p.add_argument("--table", action="store_true",
                   help="domain/pairs: also write the comparison table (table.csv/json) from the maps")
    p.add_argument("--beta", type=float, default=1.0, help="--table: weight of the mean-curvature term")
    p.add_argument("--plot", help="--table: heat map + MDS plot PNG")
    p.add_argument("--quiet", action="store_true")
    a = p.parse_args(argv)
    from .compare import parse_map_options
    try:
        if a.mode == "jobs":
            if len(a.paths) != 1:
                raise _core.InputError("jobs mode takes one JOBS.json")
            jobs = read_jobs(a.paths[0])
        else:
            need = 3 if a.mode in ("template", "domain") else 2
            if len(a.paths) < need:
                raise _core.InputError(f"{a.mode} mode needs at least {need} meshes")
            jobs = make_jobs(a.mode, a.paths)
        if a.table and a.mode not in ("domain", "pairs"):
            raise _core.InputError("--table needs the domain or pairs mode")
        if a.workers < 1:
            raise _core.InputError("--workers must be at least 1")
        opts = parse_map_options(a.map_option)
        if a.mode == "domain":  # as surfmap.compare's domain maps: genus 1 placed independent of pose
            opts = {"flat_overlay": False, **(opts or {})}
        results = run_jobs(jobs, a.out, opts, scheduler=a.scheduler, workers=a.workers,
                           threads_per_worker=a.threads_per_worker, quiet=a.quiet)
        rows = write_summary(a.out, jobs, results)
        failed = [r for r in rows if r["status"] == "failed"]
        if a.table:
            E = comparison_table(a.mode, a.paths, jobs, results, a.out, a.beta, a.plot)
            if E is None:
                print("surfmap batch: no table: some maps failed", file=sys.stderr)
    except (_core.Error, OSError) as e:
        print(f"surfmap batch: error: {e}", file=sys.stderr)
        return 1
    if not a.quiet:
        print(f"surfmap batch: {len(rows) - len(failed)} of {len(rows)} jobs finished, {len(failed)} failed; "
              f"summary in {os.path.join(a.out, 'summary.csv')}", file=sys.stderr)
        for r in failed:
            print(f"surfmap batch: failed {r['id']}: {r['error']}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
