#!/usr/bin/env python3
"""Meshes per minute of `python3 -m lapmesh.batch` over a folder, serially and on a local Dask
cluster of 1 and 2 workers (or the counts given), timed as a user runs it: the command from
start to exit, the cluster's start and shutdown included.

    PYTHONPATH=build/python python3 python/benchmarks/throughput.py [MESH_DIR] [--task reconstruct -k 30]
                                                                     [--workers 1,2] [--rounds 2] [--dask-worker]

MESH_DIR defaults to CGAL's data set in the build tree. Each configuration writes into a fresh
folder; rounds alternate the configurations, so that load from elsewhere hits each alike, and
the figure kept is the fastest round. With --dask-worker, each worker count also runs on a
cluster started as on several machines (dask-scheduler, then dask-worker --nworkers N --nthreads
1, before the batch, so its start is not timed), and the workers' minor page faults during
the batch are reported. Every run's summary must list the same meshes with the
same status, and every result file must equal the serial run's byte for byte (the batch runs
BLAS on one thread everywhere). Not a test: the figures depend on the machine and its load.
"""
import argparse
import csv
import filecmp
import os
import subprocess
import sys
import tempfile
import time


def default_meshes():
    here = os.path.dirname(os.path.abspath(__file__))
    return os.environ.get("LAPMESH_MESHES") or os.path.join(here, "..", "..", "build", "cgal-data", "data", "meshes")


def summary(out_dir, task):
    with open(os.path.join(out_dir, "summary-%s.csv" % task), newline="") as f:
        return {row["mesh"]: row for row in csv.DictReader(f)}


class Cluster:
    """dask-scheduler and dask-worker --nworkers N --nthreads 1 on this machine, ready."""

    def __init__(self, workers, env):
        import socket
        from dask.distributed import Client

        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        self.address = "tcp://127.0.0.1:%d" % port
        quiet = dict(env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.processes = [
            subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                              "--port", str(port), "--no-dashboard"], **quiet),
            subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", self.address, "--nworkers",
                              str(workers), "--nthreads", "1", "--no-dashboard"], **quiet)]
        self.client = Client(self.address, timeout=60)
        self.client.wait_for_workers(workers, timeout=60)
        self.faults_before = sum(self.client.run(_minor_faults).values())

    def close(self):
        """Stops the cluster; returns the workers' minor page faults since it was ready."""
        faults = sum(self.client.run(_minor_faults).values()) - self.faults_before
        self.client.close()
        for p in self.processes[::-1]:
            p.terminate()
            p.wait()
        return faults


def _minor_faults():
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("mesh_dir", nargs="?", default=default_meshes())
    p.add_argument("--task", default="reconstruct")
    p.add_argument("-k", type=int, default=30)
    p.add_argument("--workers", default="1,2", help="comma-separated worker counts of the local clusters")
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--dask-worker", action="store_true", help="also run on dask-scheduler + dask-worker")
    a = p.parse_args()

    configs = [("serial", ["--serial"])] + [("%s worker%s" % (w, "" if w == "1" else "s"), ["--workers", w])
                                            for w in a.workers.split(",")]
    if a.dask_worker:
        configs += [("%s dask-worker%s" % (w, "" if w == "1" else "s"), ["--dask-worker", w])
                    for w in a.workers.split(",")]
    task_args = ["--task", a.task] + (["-k", str(a.k)] if a.task in ("spectrum", "reconstruct") else [])
    # The serial run uses the threads a Dask worker uses, so that its results are the reference.
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    print("%s: %d files; task %s; %d rounds; cores %d; load average before: %.2f %.2f %.2f" % (
        a.mesh_dir, len(os.listdir(a.mesh_dir)), " ".join(task_args[1:]), a.rounds, os.cpu_count(), *os.getloadavg()))

    best, faults = {}, {}
    with tempfile.TemporaryDirectory() as scratch:
        for r in range(a.rounds):
            for name, args in configs:
                out = os.path.join(scratch, "%d-%s" % (r, name.replace(" ", "-")))
                cluster = None
                if args[0] == "--dask-worker":
                    cluster = Cluster(int(args[1]), env)
                    args = ["--scheduler", cluster.address]
                start = time.perf_counter()
                # Exit status 1: some meshes failed (recorded in the summary, compared below).
                batch = subprocess.run([sys.executable, "-m", "lapmesh.batch", a.mesh_dir, out] + task_args + args,
                                       env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
                seconds = time.perf_counter() - start
                if cluster is not None:
                    faults[name] = cluster.close()
                if batch.returncode not in (0, 1):
                    sys.exit("%s: the batch exited with status %d: %s" % (name, batch.returncode, batch.stderr[-2000:]))
                rows = summary(out, a.task)
                if name not in best or seconds < best[name][0]:
                    best[name] = (seconds, rows, out)

        ref_rows, ref_dir = best["serial"][1], best["serial"][2]
        for name, (seconds, rows, out) in best.items():
            assert sorted(rows) == sorted(ref_rows), name + ": another set of meshes"
            for mesh, row in rows.items():
                assert row["status"] == ref_rows[mesh]["status"], "%s: %s: %s" % (name, mesh, row["status"])
            names = sorted(f for f in os.listdir(ref_dir) if not f.startswith("summary") and not f.endswith(".done"))
            _, mismatch, errors = filecmp.cmpfiles(ref_dir, out, names, shallow=False)
            assert not mismatch and not errors, "%s: results differ from the serial run: %s" % (name, mismatch + errors)
        ok = sum(1 for row in ref_rows.values() if row["status"] == "ok")
        vertices = sum(int(row["vertices"]) for row in ref_rows.values() if row["status"] == "ok")
        in_tasks = sum(float(row["seconds"]) for row in ref_rows.values())
        print("%d meshes (%d ok, %d vertices in those); the serial run's tasks took %.1f s in all" % (
            len(ref_rows), ok, vertices, in_tasks))
        for name, (seconds, _, _) in best.items():
            print("%-16s %7.1f s  %6.0f meshes/min%s" % (name, seconds, 60.0 * len(ref_rows) / seconds,
                                                        "  (last round: %d minor page faults in the workers)"
                                                        % faults[name] if name in faults else ""))
        print("results equal to the serial run's, byte for byte")
    print("load average after: %.2f %.2f %.2f" % os.getloadavg())
    return 0


if __name__ == "__main__":
    sys.exit(main())
