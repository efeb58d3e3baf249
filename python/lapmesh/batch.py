"""Run one lapmesh operation over a folder of meshes, one task per mesh, on Dask.

    python3 -m lapmesh.batch MESH_DIR OUT_DIR --task curvature|spectrum|reconstruct|smooth|denoise-study
                             [--workers N [--memory-limit 4GB] | --scheduler tcp://HOST:8786 | --serial]

Per mesh STEM and task TASK it writes OUT_DIR/STEM.TASK.{csv,off} in the command line's
formats (17 significant digits), for spectrum also STEM.spectrum.npz (the eigenpairs), atomically,
then OUT_DIR/STEM.TASK.done (its summary row). A mesh that fails is recorded (status failed, the
error's type and message, without the file's path) and the others go on. A second run skips the meshes whose outputs and .done file
exist, so a killed batch resumes where it stopped. The summary is OUT_DIR/summary-TASK.csv: mesh,
vertices, faces, status, error, seconds, peak_mib (the peak resident memory of the process while
it ran that mesh, in MiB: the kernel's high-water mark VmHWM, reset before the mesh through
/proc/self/clear_refs; it includes the process's own baseline). On a Dask worker with a memory
limit, a mesh whose task needs more than the worker has left (by a lower estimate, from the
file's header and then from the mesh) fails with a MemoryError before it is computed.

Dask's workers run BLAS and OpenMP on one thread (distributed's distributed.nanny.pre-spawn-environ:
OMP_NUM_THREADS=1, OPENBLAS_NUM_THREADS=1). The sparse Cholesky and the block Lanczos round
differently with another thread count, so the spectral and implicit-smoothing outputs are those
of a serial run (--serial, or the command line) with the same variables, bit for bit.
"""
import argparse
import csv
import io
import json
import os
import sys
import tempfile
import time

MESH_EXTENSIONS = (".off", ".obj", ".ply", ".stl")
TASKS = ("curvature", "spectrum", "reconstruct", "smooth", "denoise-study")
COLUMNS = ("mesh", "vertices", "faces", "status", "error", "seconds", "peak_mib")


def _write_atomically(path, data):
    """Writes `data` (str, or a function writing to a binary file) to `path` through a temporary
    file in the same folder and a rename."""
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix="-" + os.path.basename(path))
    try:
        binary = callable(data)
        with os.fdopen(fd, "wb" if binary else "w", newline=None if binary else "") as f:
            if binary:
                data(f)
            else:
                f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _g17(x):
    return "%.17g" % x


def outputs(out_dir, stem, task):
    """(result file, completion file) of a mesh (spectrum also writes an .npz: see results())."""
    ext = "off" if task in ("reconstruct", "smooth") else "csv"
    return (os.path.join(out_dir, "%s.%s.%s" % (stem, task, ext)), os.path.join(out_dir, "%s.%s.done" % (stem, task)))


def results(out_dir, stem, task):
    """Every result file of a mesh: a mesh is complete when these and its completion file exist."""
    result, _ = outputs(out_dir, stem, task)
    return [result] + ([os.path.join(out_dir, "%s.spectrum.npz" % stem)] if task == "spectrum" else [])


# ---- memory ----
# Bytes per vertex that a task needs at least, above the process's resident memory before it:
# reading a mesh, and each task's work; spectrum and reconstruct add SPECTRAL_BYTES_PER_PAIR per
# vertex and pair. Set below the peaks measured on CGAL's meshes (doc/cluster.md), so that a mesh
# is refused only when it cannot fit.
READ_BYTES_PER_VERTEX = 400
TASK_BYTES_PER_VERTEX = {"curvature": 400, "spectrum": 1000, "reconstruct": 1000, "smooth": 1000,
                         "denoise-study": 1000}
SPECTRAL_BYTES_PER_PAIR = 16


def estimate_bytes(task, vertices, k=0):
    """A lower estimate of the memory (bytes) that reading a mesh of `vertices` vertices and
    running `task` on it needs above the process's memory before it."""
    per_vertex = READ_BYTES_PER_VERTEX + TASK_BYTES_PER_VERTEX[task]
    if task in ("spectrum", "reconstruct"):
        per_vertex += SPECTRAL_BYTES_PER_PAIR * min(k, vertices)
    return per_vertex * vertices


def _proc_status_kib(field):
    """A field of /proc/self/status in KiB (VmRSS, VmHWM), or None off Linux."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return int(line.split()[1])
    except OSError:
        pass
    return None


def _reset_peak():
    """Sets this process's peak resident memory (VmHWM) to its current one; False where the
    kernel does not permit it (then the peak is the process's since it started)."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def _peak_mib():
    """This process's peak resident memory in MiB (VmHWM; ru_maxrss off Linux)."""
    kib = _proc_status_kib("VmHWM")
    if kib is None:
        import resource

        kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        if sys.platform == "darwin":  # bytes there
            kib //= 1024
    return round(kib / 1024.0, 1)


def _worker_memory_left():
    """(bytes this Dask worker may still take before its nanny stops it, its memory limit), or
    None outside a worker with a memory limit."""
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):
        return None
    manager = getattr(worker, "memory_manager", worker)
    limit = getattr(manager, "memory_limit", None)
    rss = _proc_status_kib("VmRSS")
    if not limit or rss is None:
        return None
    import dask

    fraction = dask.config.get("distributed.worker.memory.terminate", 0.95) or 1.0
    return int(limit * fraction) - rss * 1024, int(limit)


def _declared_vertices(path):
    """The vertex count an OFF or PLY file's header declares (cheap: the mesh is not read), or
    None; None too for a count the file is too small to hold (the reader reports that file)."""
    try:
        with open(path, "rb") as f:
            head = f.read(65536)
        size = os.path.getsize(path)
    except OSError:
        return None
    count = _header_vertices(path, head)
    # at least 6 bytes a vertex in text ("0 0 0\n"), 12 in binary
    return count if count is not None and 0 <= count and 6 * count <= size else None


def _header_vertices(path, head):
    """The vertex count in the first bytes `head` of an OFF or PLY file, or None."""
    lower = path.lower()
    try:
        if lower.endswith(".off"):
            tokens = []
            for line in head.split(b"\n")[:64]:
                tokens += line.split(b"#")[0].split()
                if len(tokens) >= 2:
                    break
            if tokens and tokens[0].endswith(b"OFF"):
                tokens = tokens[1:]
            return int(tokens[0]) if tokens else None
        if lower.endswith(".ply"):
            for line in head.split(b"\n"):
                words = line.split()
                if words[:2] == [b"element", b"vertex"] and len(words) == 3:
                    return int(words[2])
                if words[:1] == [b"end_header"]:
                    break
    except ValueError:
        pass
    return None


def _check_memory(task, vertices, options):
    """Raises MemoryError when a Dask worker's memory limit cannot hold the task on this many
    vertices (by estimate_bytes, a lower estimate): the mesh fails with a message instead of
    the worker being killed by its nanny. Nothing outside a worker with a memory limit."""
    left = _worker_memory_left()
    if left is None or vertices is None:
        return
    need = estimate_bytes(task, vertices, options.get("k") or 0)
    if need > left[0]:
        mib = 1024.0 * 1024.0
        raise MemoryError("%s on %d vertices needs at least %.0f MiB; this worker has %.0f MiB left under its "
                          "memory limit of %.0f MiB (give the workers more memory: --memory-limit)"
                          % (task, vertices, need / mib, max(left[0], 0) / mib, left[1] / mib))


def process(path, out_dir, task, options):
    """Runs `task` on the mesh at `path`; returns its summary row (never raises)."""
    import lapmesh
    import warnings

    stem = os.path.splitext(os.path.basename(path))[0]
    result, done = outputs(out_dir, stem, task)
    row = {"mesh": os.path.basename(path), "vertices": "", "faces": "", "status": "ok", "error": "", "seconds": "",
           "peak_mib": ""}
    restore_adaptive_malloc()
    lapmesh.release_working_memory()  # the previous task's arrays would count in this task's peak
    start = time.perf_counter()
    _reset_peak()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", lapmesh.LapmeshWarning)
            _check_memory(task, _declared_vertices(path), options)  # before reading a mesh too big to read
            V, F = lapmesh.read_mesh(path)
            row["vertices"], row["faces"] = len(V), len(F)
            _check_memory(task, len(V), options)
            shape = dict(laplacian=options["laplacian"], area=options["area"])
            if task == "curvature":
                c = lapmesh.curvatures(V, F, **shape)
                text = io.StringIO()
                text.write("vertex,mean,gaussian,k1,k2\n")
                for i, values in enumerate(zip(c.mean, c.gaussian, c.k1, c.k2)):
                    text.write("%d,%s\n" % (i, ",".join(map(_g17, values))))
                _write_atomically(result, text.getvalue())
            elif task == "spectrum":
                k = _pairs(options["k"], F)
                basis = lapmesh.SpectralBasis(V, F, k, **shape)
                _write_atomically(results(out_dir, stem, task)[1], lambda f: _save_npz(f, basis))
                _write_atomically(result, "index,eigenvalue\n" + "".join(
                    "%d,%s\n" % (i, _g17(x)) for i, x in enumerate(basis.values[:k])))
            elif task == "reconstruct":
                k = _pairs(options["k"], F)
                lapmesh.write_mesh(result, lapmesh.SpectralBasis(V, F, k, **shape).reconstruct(k), F)
            elif task == "denoise-study":
                study = {key: options[key] for key in ("levels", "schemes", "laplacians", "lambdas", "iterations",
                                                        "seed") if options.get(key) is not None}
                r = lapmesh.denoise_study(V, F, area=options["area"], **study)
                _write_atomically(result, _study_csv(r, lapmesh.denoise_study.__doc__))
            elif task == "smooth":
                V2, _ = lapmesh.smooth(V, F, scheme=options["scheme"], lam=options["lam"],
                                       iterations=options["iterations"], **shape)
                lapmesh.write_mesh(result, V2, F)
            else:
                raise ValueError("unknown task %r" % task)
    except Exception as e:  # recorded, never stops the batch
        message = str(e)
        # The mesh column names the file: the reader's "PATH: " would add only this machine's folders,
        # and only to the errors found while reading.
        if message.startswith(path + ": "):
            message = message[len(path) + 2:]
        row["status"], row["error"] = "failed", "%s: %s" % (type(e).__name__, message)
    row["seconds"] = round(time.perf_counter() - start, 6)
    row["peak_mib"] = _peak_mib()
    if row["status"] == "ok":
        _write_atomically(done, json.dumps(row))
    return row


def _pairs(k, F):
    """k, at most the operator's size: the vertices in faces (a vertex in no face has no row)."""
    import numpy as np

    return min(k, np.unique(F).size)


def _save_npz(f, basis):
    """The eigenpairs as numpy arrays (what the basis file of `lapmesh reconstruct --save-basis`
    holds): every pair the basis holds, the mass diagonal, the k asked for, the operator's names."""
    import numpy as np

    np.savez(f, values=basis.values, vectors=basis.vectors, mass=basis.mass, k=np.int64(basis.k),
             laplacian=np.str_(basis.laplacian), area=np.str_(basis.area))


def _csv_field(text):
    return "" if not text else '"' + text.replace('"', '""').replace("\n", " ").replace("\r", " ") + '"'


def _study_csv(r, doc):
    """The table of `lapmesh denoise-study` (its columns and number format)."""
    unit = doc.split("lambda_unit: str = '")[1].split("'")[0]
    lines = ["noise_level,sigma,scheme,laplacian,lambda_%s,lambda,stability_bound,iteration,rms_distance,"
             "hausdorff_distance,normal_angle_error_deg,volume_change,status,error" % unit]
    for i in range(len(r["iteration"])):
        lines.append(",".join([_g17(r["noise_level"][i]), _g17(r["sigma"][i]), r["scheme"][i], r["laplacian"][i],
                               _g17(r["time_step"][i]), _g17(r["lambda"][i]), _g17(r["stability_bound"][i]),
                               str(int(r["iteration"][i])), _g17(r["rms_distance"][i]),
                               _g17(r["hausdorff_distance"][i]), _g17(r["normal_angle_error"][i]),
                               _g17(r["volume_change"][i]), r["status"][i], _csv_field(r["error"][i])]))
    return "\n".join(lines) + "\n"


_malloc_checked = False


def restore_adaptive_malloc():
    """In a process started with MALLOC_TRIM_THRESHOLD_ set, sets glibc's mmap threshold to the
    largest value its adaptive threshold reaches (32 MiB) and the trim threshold to twice that, as
    the adaptive rule does. distributed's nanny sets that variable for every worker it starts (a
    local cluster's and `dask-worker`'s alike), and setting any malloc threshold turns glibc's
    adaptive rule off: every block over 128 KiB is then mapped and page-faulted afresh at each use,
    which made the tasks markedly slower on a worker than in a serial run (doc/cluster.md).
    Importing lapmesh sets the same thresholds, but leaves those the environment sets. Each task
    calls it; it acts once per process. Returns whether it changed the thresholds (False without
    the variable, with MALLOC_MMAP_THRESHOLD_ set by the user, or without glibc)."""
    global _malloc_checked
    if _malloc_checked:
        return False
    _malloc_checked = True
    if "MALLOC_TRIM_THRESHOLD_" not in os.environ or "MALLOC_MMAP_THRESHOLD_" in os.environ:
        return False  # glibc's default, or thresholds the user chose
    from . import _lapmesh

    return _lapmesh._set_steady_heap_thresholds()


def find_meshes(mesh_dir):
    return sorted(os.path.join(mesh_dir, f) for f in os.listdir(mesh_dir)
                  if f.lower().endswith(MESH_EXTENSIONS) and os.path.isfile(os.path.join(mesh_dir, f)))


def run(mesh_dir, out_dir, task, options, workers=None, scheduler=None, serial=False, progress=None,
        memory_limit="auto"):
    """Runs the batch; returns the summary rows (sorted by mesh) and writes summary-TASK.csv."""
    if task not in TASKS:
        raise ValueError("unknown task %r (expected one of: %s)" % (task, ", ".join(TASKS)))
    os.makedirs(out_dir, exist_ok=True)
    rows, todo = [], []
    for path in find_meshes(mesh_dir):
        stem = os.path.splitext(os.path.basename(path))[0]
        _, done = outputs(out_dir, stem, task)
        if os.path.exists(done) and all(os.path.exists(f) for f in results(out_dir, stem, task)):
            with open(done) as f:
                row = json.load(f)
            row["status"] = "skipped"  # completed by an earlier run
            rows.append(row)
        else:
            todo.append(path)
    if serial:
        for i, path in enumerate(todo):
            rows.append(process(path, out_dir, task, options))
            if progress:
                progress(i + 1, len(todo))
    elif todo:
        from dask.distributed import Client, LocalCluster, as_completed

        cluster = None
        # distributed's nannies write their pre-spawn environment (OMP_NUM_THREADS=1, ...) into
        # this process's os.environ: it is restored afterwards, for the caller's later children.
        environ = dict(os.environ)
        if scheduler:
            client = Client(scheduler)
        else:
            # A worker past its memory limit is restarted by its nanny: its mesh fails (KilledWorker).
            cluster = LocalCluster(n_workers=workers or os.cpu_count(), threads_per_worker=1, processes=True,
                                   dashboard_address=None, memory_limit=memory_limit)
            client = Client(cluster)
        try:
            futures = client.map(process, todo, out_dir=out_dir, task=task, options=options, pure=False)
            for i, future in enumerate(as_completed(futures)):
                try:
                    rows.append(future.result())
                except Exception as e:  # a worker died (memory limit, kill): the mesh fails, the batch goes on
                    path = todo[futures.index(future)]
                    why = "%s: %s" % (type(e).__name__, e)
                    if type(e).__name__ == "KilledWorker":
                        why = "KilledWorker: the workers that ran this mesh died (past their memory limit, or " \
                              "killed); Dask: %s" % e
                    rows.append({"mesh": os.path.basename(path), "vertices": "", "faces": "", "status": "failed",
                                 "error": why, "seconds": "", "peak_mib": ""})
                if progress:
                    progress(i + 1, len(todo))
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
            os.environ.clear()
            os.environ.update(environ)
    rows.sort(key=lambda r: r["mesh"])
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=COLUMNS, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    _write_atomically(os.path.join(out_dir, "summary-%s.csv" % task), text.getvalue())
    return rows


def main(argv=None):
    import lapmesh

    p = argparse.ArgumentParser(prog="python3 -m lapmesh.batch", description=__doc__.split("\n\n")[0])
    p.add_argument("mesh_dir")
    p.add_argument("out_dir")
    p.add_argument("--task", required=True, choices=TASKS)
    p.add_argument("-k", type=int, default=30, help="eigenpairs (spectrum, reconstruct; at most the vertices in faces)")
    p.add_argument("--laplacian", default=None, choices=lapmesh.names("laplacian"))
    p.add_argument("--area", default=None, choices=lapmesh.names("area"))
    p.add_argument("--scheme", default=None, choices=lapmesh.names("scheme"))
    p.add_argument("--lambda", dest="lam", default="auto", help="smoothing time step or 'auto'")
    p.add_argument("--iterations", type=int, default=None, help="smoothing steps (smooth: 1; denoise-study: its default)")
    p.add_argument("--levels", help="denoise-study: comma-separated noise levels")
    p.add_argument("--schemes", help="denoise-study: comma-separated schemes")
    p.add_argument("--laplacians", help="denoise-study: comma-separated Laplacians")
    p.add_argument("--lambdas", help="denoise-study: comma-separated time steps (in its default unit)")
    p.add_argument("--seed", type=int, default=None, help="denoise-study: the noise's seed")
    p.add_argument("--memory-limit", default="auto", help="local cluster: memory per worker, e.g. 4GB (Dask's syntax)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, help="local cluster workers (default: one per core)")
    where.add_argument("--scheduler", help="address of a running Dask scheduler, e.g. tcp://HOST:8786")
    where.add_argument("--serial", action="store_true", help="no Dask: one mesh after another in this process")
    a = p.parse_args(argv)
    # Unset options take the library's defaults (the compiled functions' own).
    def numbers(text):
        return None if text is None else [float(x) for x in text.split(",")]

    def words(text):
        return None if text is None else text.split(",")

    options = {"k": a.k, "lam": a.lam, "levels": numbers(a.levels), "lambdas": numbers(a.lambdas),
               "schemes": words(a.schemes), "laplacians": words(a.laplacians), "seed": a.seed,
               "iterations": a.iterations if a.iterations is not None else (None if a.task == "denoise-study" else 1)}
    for key in ("laplacian", "area", "scheme"):
        options[key] = getattr(a, key) if getattr(a, key) is not None else _default(key)
    tty = sys.stderr.isatty()

    def progress(done, total):
        if tty:
            sys.stderr.write("\r%d/%d meshes" % (done, total) + ("\n" if done == total else ""))
            sys.stderr.flush()

    rows = run(a.mesh_dir, a.out_dir, a.task, options, workers=a.workers, scheduler=a.scheduler, serial=a.serial,
               progress=progress, memory_limit=a.memory_limit)
    counts = {}
    for r in rows:
        counts[r["status"]] = counts.get(r["status"], 0) + 1
    print("%d meshes: %s; summary in %s" % (len(rows), ", ".join("%d %s" % (n, s) for s, n in sorted(counts.items())),
                                             os.path.join(a.out_dir, "summary-%s.csv" % a.task)))
    return 1 if counts.get("failed") else 0


def _default(key):
    """The default of an option as the compiled module's signature shows it."""
    import lapmesh

    fn = lapmesh.smooth
    signature = fn.__doc__.splitlines()[0]
    marker = "%s: str = '" % key
    start = signature.index(marker) + len(marker)
    return signature[start:signature.index("'", start)]


if __name__ == "__main__":
    # Through the importable module, not this __main__: Dask then sends the workers a reference
    # to lapmesh.batch.process, which they import from their own lapmesh, not this file's code.
    from lapmesh import batch

    sys.exit(batch.main())
