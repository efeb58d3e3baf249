"""python3 -m lapmesh.batch: a local Dask cluster of 2 worker processes gives the serial run's
outputs byte for byte on 40 meshes of CGAL's data set; a broken mesh is reported while the
others finish; a re-run skips what is complete and redoes only what is missing; the summary's
peak memory, the spectrum's .npz, a worker's memory limit, a cluster started by dask-scheduler
and dask-worker, and glibc's malloc thresholds on a worker."""
import csv
import filecmp
import os
import subprocess
import sys

import pytest

from lapmesh import batch

from conftest import torus


def off_vertices(path):
    with open(path) as f:
        tokens = f.read(4096).split()
    return int(tokens[1]) if tokens and tokens[0] == "OFF" else -1


def make_corpus(meshes, folder, count):
    """The first `count` OFF meshes of CGAL's data set with 10 to 3,000 vertices (every kind the
    folder has: closed, open, polygons), linked into `folder`, and a broken one."""
    chosen = [f for f in sorted(os.listdir(meshes))
              if f.endswith(".off") and 10 <= off_vertices(os.path.join(meshes, f)) <= 3000][:count]
    assert len(chosen) == count, chosen
    for f in chosen:
        os.symlink(os.path.join(meshes, f), folder / f)
    (folder / "zz_broken.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\nnan 0 0\n3 0 1 2\n")
    return str(folder), chosen


@pytest.fixture(scope="module")
def corpus(meshes, tmp_path_factory):
    """12 small meshes of CGAL's data set and a broken one."""
    return make_corpus(meshes, tmp_path_factory.mktemp("corpus"), 12)


@pytest.fixture(scope="module")
def corpus40(meshes, tmp_path_factory):
    """40 small meshes of CGAL's data set (the 12 of corpus among them) and a broken one."""
    return make_corpus(meshes, tmp_path_factory.mktemp("corpus40"), 40)


def read_summary(path):
    with open(path) as f:
        return {row["mesh"]: row for row in csv.DictReader(f)}


OPTIONS = dict(k=10, laplacian="cotangent", area="barycentric", scheme="implicit", lam="auto", iterations=2)


def serial_run(folder, out, task):
    """The batch with --serial in a process with the Dask workers' environment (their BLAS and
    OpenMP thread counts: the rounding of the spectral solver depends on them)."""
    import dask
    import distributed  # noqa: F401 (loads distributed's configuration)

    env = dict(os.environ)
    env.update({k: str(v) for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items()})
    r = subprocess.run([sys.executable, "-m", "lapmesh.batch", folder, out, "--task", task, "-k", str(OPTIONS["k"]),
                        "--serial"], capture_output=True, text=True, env=env)
    assert r.returncode == 1, r.stderr  # the broken mesh fails
    return [dict(row, vertices=int(row["vertices"] or 0) or "", faces=int(row["faces"] or 0) or "")
            for row in read_summary(os.path.join(out, "summary-%s.csv" % task)).values()]


@pytest.mark.parametrize("task", ["curvature", "reconstruct"])
def test_dask_equals_serial(corpus40, tmp_path, task):
    folder, chosen = corpus40
    environ = dict(os.environ)
    serial = serial_run(folder, str(tmp_path / "serial"), task)
    dask = batch.run(folder, str(tmp_path / "dask"), task, OPTIONS, workers=2)
    assert dict(os.environ) == environ  # the cluster's settings do not leak into this process
    assert [r["mesh"] for r in serial] == [r["mesh"] for r in dask] == chosen + ["zz_broken.off"]
    for s, d in zip(serial, dask):
        assert (s["status"], s["vertices"], s["faces"]) == (d["status"], d["vertices"], d["faces"])
        assert s["error"] == d["error"]
        if s["status"] == "ok":
            result, _ = batch.outputs(str(tmp_path / "serial"), os.path.splitext(s["mesh"])[0], task)
            other, _ = batch.outputs(str(tmp_path / "dask"), os.path.splitext(s["mesh"])[0], task)
            assert filecmp.cmp(result, other, shallow=False), result
    # every chosen mesh succeeds (boeing.off's 122 components included), the broken one fails
    assert sum(r["status"] == "ok" for r in dask) == len(chosen), [r for r in dask if r["status"] != "ok"]
    broken = dask[-1]
    assert broken["status"] == "failed" and "MeshError" in broken["error"] and "non-finite" in broken["error"]
    assert broken["error"].startswith("MeshError: ") and folder not in broken["error"], broken["error"]
    summary = read_summary(tmp_path / "dask" / ("summary-%s.csv" % task))
    assert set(summary) == set(chosen) | {"zz_broken.off"}
    assert list(next(iter(summary.values()))) == list(batch.COLUMNS)
    assert all(float(row["peak_mib"]) > 0 for row in summary.values())  # a worker's peak resident memory


def test_curvature_file_is_the_cli_csv(corpus, cli, tmp_path):
    folder, chosen = corpus
    batch.run(folder, str(tmp_path), "curvature", OPTIONS, serial=True)
    for name in chosen[:3]:
        cli("curvature", os.path.join(folder, name), "-o", tmp_path / "cli.csv", "-q")
        result, _ = batch.outputs(str(tmp_path), os.path.splitext(name)[0], "curvature")
        assert filecmp.cmp(result, tmp_path / "cli.csv", shallow=False), name


def test_rerun_skips_completed_meshes(corpus, tmp_path):
    folder, chosen = corpus
    out = str(tmp_path)
    batch.run(folder, out, "curvature", OPTIONS, serial=True)
    # a batch killed before one mesh finished: its outputs are missing, a temporary file may remain
    stem = os.path.splitext(chosen[4])[0]
    result, done = batch.outputs(out, stem, "curvature")
    os.unlink(done)
    os.unlink(result)
    (tmp_path / (".tmp-xyz-" + os.path.basename(result))).write_text("partial")
    before = {f: os.stat(os.path.join(out, f)).st_mtime_ns for f in os.listdir(out) if f.endswith(".csv") and not f.startswith("summary")}
    rows = {r["mesh"]: r for r in batch.run(folder, out, "curvature", OPTIONS, workers=2)}
    assert rows[chosen[4]]["status"] == "ok"
    assert all(rows[m]["status"] == "skipped" for m in chosen if m != chosen[4])
    assert rows["zz_broken.off"]["status"] == "failed"
    for f, t in before.items():
        assert os.stat(os.path.join(out, f)).st_mtime_ns == t, f + " was recomputed"
    assert os.path.exists(result)


def test_command_line(corpus, tmp_path):
    folder, chosen = corpus
    r = subprocess.run([sys.executable, "-m", "lapmesh.batch", folder, str(tmp_path), "--task", "spectrum", "-k", "5",
                        "--serial"], capture_output=True, text=True)
    assert r.returncode == 1, r.stderr  # the broken mesh
    assert "13 meshes: 1 failed, 12 ok" in r.stdout, r.stdout
    with open(batch.outputs(str(tmp_path), os.path.splitext(chosen[0])[0], "spectrum")[0]) as f:
        lines = f.read().splitlines()
    assert lines[0] == "index,eigenvalue" and len(lines) == 6
    summary = read_summary(tmp_path / "summary-spectrum.csv")
    assert all(float(row["peak_mib"]) > 0 for row in summary.values())
    bad = subprocess.run([sys.executable, "-m", "lapmesh.batch", folder, str(tmp_path), "--task", "spectrum",
                          "--laplacian", "nope"], capture_output=True, text=True)
    assert bad.returncode == 2 and "invalid choice" in bad.stderr


def test_denoise_study_file_is_the_cli_csv(meshes, cli, tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    os.symlink(os.path.join(meshes, "head.off"), folder / "head.off")
    r = subprocess.run([sys.executable, "-m", "lapmesh.batch", str(folder), str(tmp_path / "out"), "--task",
                        "denoise-study", "--levels", "0.05", "--lambdas", "0.1,1", "--iterations", "2", "--seed", "3",
                        "--serial"], capture_output=True, text=True, env=cli.env)
    assert r.returncode == 0, r.stderr
    cli("denoise-study", folder / "head.off", "-o", tmp_path / "cli.csv", "--levels", "0.05", "--lambdas", "0.1,1",
        "--iterations", 2, "--seed", 3, "-q", "--no-progress")
    result, _ = batch.outputs(str(tmp_path / "out"), "head", "denoise-study")
    assert filecmp.cmp(result, tmp_path / "cli.csv", shallow=False)


def test_killed_batch_resumes(corpus, tmp_path):
    """A batch killed midway, run again: the meshes done before are not recomputed, the rest are."""
    import signal
    import time

    folder, chosen = corpus
    out = tmp_path / "out"
    args = [sys.executable, "-m", "lapmesh.batch", folder, str(out), "--task", "spectrum", "-k", "40", "--serial"]
    p = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    while time.time() < deadline and p.poll() is None:
        if out.exists() and len([f for f in os.listdir(out) if f.endswith(".done")]) >= 3:
            break
        time.sleep(0.005)
    p.send_signal(signal.SIGKILL)
    p.wait()
    done_before = {f: os.stat(out / f).st_mtime_ns for f in os.listdir(out) if f.endswith(".done")}
    assert 3 <= len(done_before) < 12, sorted(done_before)  # killed midway
    r = subprocess.run(args, capture_output=True, text=True)
    assert r.returncode == 1, r.stdout + r.stderr  # the broken mesh (and any mesh the solver fails on)
    summary = read_summary(out / "summary-spectrum.csv")
    assert summary["zz_broken.off"]["status"] == "failed"
    for name in chosen:
        stem = os.path.splitext(name)[0]
        status = summary[name]["status"]
        if stem + ".spectrum.done" in done_before:
            assert status == "skipped", name
        else:
            assert status in ("ok", "failed"), name
        assert os.path.exists(batch.outputs(str(out), stem, "spectrum")[0]) == (status != "failed"), name
    for f, t in done_before.items():
        assert os.stat(out / f).st_mtime_ns == t, f + " was recomputed"


def free_port():
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_running_scheduler(corpus, tmp_path):
    """--scheduler with a scheduler and a worker started as on a cluster (dask-scheduler and
    dask-worker, as doc/cluster.md's walkthrough does): the batch completes, and the worker ran
    its own lapmesh.batch.process (sent by reference, not as the command line's __main__ code),
    which restored glibc's adaptive malloc thresholds in that worker."""
    import time
    from dask.distributed import Client

    folder, chosen = corpus
    address = "tcp://127.0.0.1:%d" % free_port()
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    cli = [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port",
           address.rsplit(":", 1)[1], "--no-dashboard"]
    scheduler = subprocess.Popen(cli, **quiet)
    worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
                               "--no-dashboard"], **quiet)
    try:
        with Client(address, timeout=60) as client:
            client.wait_for_workers(1, timeout=60)
            r = subprocess.run([sys.executable, "-m", "lapmesh.batch", folder, str(tmp_path), "--task", "curvature",
                                "--scheduler", address], capture_output=True, text=True, timeout=300)
            assert r.returncode == 1, r.stdout + r.stderr  # the broken mesh
            def worker_state():
                import resource

                import numpy as np
                from lapmesh import batch as worker_batch

                before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
                for _ in range(20):
                    np.ones(1 << 19).sum()  # a 4 MiB block, as in test_restore_adaptive_malloc
                faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
                return worker_batch._malloc_checked, os.environ.get("MALLOC_TRIM_THRESHOLD_"), faults
            (state,) = client.run(worker_state).values()
        assert state[0] is True and state[1] is not None  # the task's answer to the nanny's variable
        # Its effect in that worker: the blocks reuse freed memory instead of faulting every page.
        assert state[2] < 20 * 1024 / 10, state
        rows = read_summary(tmp_path / "summary-curvature.csv")
        assert [m for m, row in rows.items() if row["status"] == "ok"] == chosen
        assert rows["zz_broken.off"]["status"] == "failed"
    finally:
        for p in (worker, scheduler):
            p.terminate()
        deadline = time.time() + 30
        for p in (worker, scheduler):
            try:
                p.wait(max(1, deadline - time.time()))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def test_spectrum_npz_is_the_basis(corpus, tmp_path):
    """--task spectrum writes STEM.spectrum.npz: numpy.load gives SpectralBasis's eigenpairs, bit for bit;
    a mesh whose .npz is missing is computed again."""
    import warnings

    import numpy as np

    import lapmesh

    folder, chosen = corpus
    options = dict(OPTIONS, laplacian="cotangent", area="mixed")
    rows = {r["mesh"]: r for r in batch.run(folder, str(tmp_path), "spectrum", options, serial=True)}
    checked = 0
    for name in chosen[:4]:
        if rows[name]["status"] != "ok":
            continue
        stem = os.path.splitext(name)[0]
        result, npz = batch.results(str(tmp_path), stem, "spectrum")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", lapmesh.LapmeshWarning)  # polygons triangulated, as the batch does
            V, F = lapmesh.read_mesh(os.path.join(folder, name))
        basis = lapmesh.SpectralBasis(V, F, min(options["k"], len(V)), laplacian="cotangent", area="mixed")
        with np.load(npz) as z:
            assert sorted(z.files) == ["area", "k", "laplacian", "mass", "values", "vectors"]
            for key in ("values", "vectors", "mass"):
                expected = getattr(basis, key)
                assert z[key].dtype == expected.dtype and z[key].shape == expected.shape, (name, key)
                assert z[key].tobytes() == expected.tobytes(), (name, key)
            assert int(z["k"]) == basis.k and str(z["laplacian"]) == "cotangent" and str(z["area"]) == "mixed"
        with open(result) as f:
            assert len(f.read().splitlines()) == basis.k + 1
        checked += 1
    assert checked >= 3
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".tmp-")]
    stem = os.path.splitext(chosen[0])[0]
    os.unlink(batch.results(str(tmp_path), stem, "spectrum")[1])
    again = {r["mesh"]: r["status"] for r in batch.run(folder, str(tmp_path), "spectrum", options, serial=True)}
    assert again[chosen[0]] == "ok" and again[chosen[1]] == "skipped"
    assert os.path.exists(batch.results(str(tmp_path), stem, "spectrum")[1])


def test_worker_memory_limit(corpus, tmp_path):
    """A worker with a 300 MB memory limit and two meshes too big for it: an OFF torus of 409,600
    vertices, refused from its header's vertex count before it is read (reading alone would take
    the worker near its limit), and an OBJ torus of 160,000 vertices (no count in the header),
    which the worker can read, refused then, before its spectrum is computed. Both fail with a
    MemoryError that says why; the worker stays up and the other meshes are done."""
    import lapmesh

    folder, chosen = corpus
    meshes = tmp_path / "in"
    meshes.mkdir()
    small = chosen[:3]
    for name in small:
        os.symlink(os.path.join(folder, name), meshes / name)
    lapmesh.write_mesh(str(meshes / "big_torus.off"), *torus(640, 640))
    lapmesh.write_mesh(str(meshes / "mid_torus.obj"), *torus(400, 400))
    environ = dict(os.environ)
    rows = {r["mesh"]: r for r in batch.run(str(meshes), str(tmp_path / "out"), "spectrum", OPTIONS, workers=1,
                                            memory_limit="300MB")}
    os.environ.clear()
    os.environ.update(environ)
    for name, vertices, read in (("big_torus.off", 409600, False), ("mid_torus.obj", 160000, True)):
        row = rows[name]
        assert row["status"] == "failed", row
        assert row["error"].startswith("MemoryError: spectrum on %d vertices needs at least " % vertices) and \
            "memory limit of 286 MiB" in row["error"], row["error"]
        assert row["vertices"] == (vertices if read else ""), row
        assert not os.path.exists(batch.outputs(str(tmp_path / "out"), os.path.splitext(name)[0], "spectrum")[1])
    assert all(rows[name]["status"] == "ok" for name in small), rows
    summary = read_summary(tmp_path / "out" / "summary-spectrum.csv")
    assert summary["big_torus.off"]["status"] == "failed" and "MemoryError" in summary["big_torus.off"]["error"]
    assert float(summary["mid_torus.obj"]["peak_mib"]) < 286


def test_k_is_clipped_to_the_vertices_in_faces(tmp_path):
    """-k above the operator's size: a tetrahedron with two vertices in no face gives its 4 pairs."""
    folder = tmp_path / "in"
    folder.mkdir()
    (folder / "tet.off").write_text("OFF\n6 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n5 5 5\n6 6 6\n"
                                    "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n")
    out = str(tmp_path / "out")
    for task in ("spectrum", "reconstruct"):
        rows = batch.run(str(folder), out, task, dict(OPTIONS, k=30), serial=True)
        assert rows[0]["status"] == "ok", rows[0]["error"]
    with open(batch.outputs(out, "tet", "spectrum")[0]) as f:
        assert len(f.read().splitlines()) == 1 + 4


FAULTS_OF_FRESH_BLOCKS = r"""
import resource, sys
import numpy as np
from lapmesh import batch

def faults():
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(20):
        np.ones(1 << 19).sum()  # a 4 MiB block, allocated, touched and freed
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before

before = faults()
changed = batch.restore_adaptive_malloc()
again = batch.restore_adaptive_malloc()
faults()  # the heap grows once to hold such a block
print(before, int(changed), int(again), faults())
"""


@pytest.mark.parametrize("variable", [True, False])
def test_restore_adaptive_malloc(variable):
    """A worker started with distributed's MALLOC_TRIM_THRESHOLD_ page-faults every large block
    afresh; restore_adaptive_malloc (called by each task) makes such blocks reuse freed memory.
    Without the variable it changes nothing."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    if variable:
        env["MALLOC_TRIM_THRESHOLD_"] = "65536"
    r = subprocess.run([sys.executable, "-c", FAULTS_OF_FRESH_BLOCKS], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    before, changed, again, after = map(int, r.stdout.split())
    assert (changed, again) == (int(variable), 0)
    # With the variable and no fix every block faults all its pages afresh, so `after` stays near
    # `before`; fixed, the blocks reuse freed heap memory.
    # (Where the kernel backs the blocks with huge pages, both counts are small.)
    assert after <= before / 10 + 100, (before, after)
