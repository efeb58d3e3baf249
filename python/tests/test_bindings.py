"""Every binding against the command line on CGAL's meshes: the same code runs on both sides,
so the results agree bitwise (the CLI writes 17 significant digits, read back with float())."""
import math
import os
import re
import subprocess
import sys
import warnings

import numpy as np
import pytest

import lapmesh

from conftest import torus


def read_off(path):
    """A minimal OFF reader (the CLI's output), independent of the library."""
    with open(path) as f:
        tokens = f.read().split()
    assert tokens[0] == "OFF"
    n, m = int(tokens[1]), int(tokens[2])
    V = np.array([float(t) for t in tokens[4:4 + 3 * n]]).reshape(n, 3)
    rest = tokens[4 + 3 * n:]
    F = np.array([[int(x) for x in rest[4 * i + 1:4 * i + 4]] for i in range(m)], dtype=np.int64)
    return V, F


def read_csv(path):
    with open(path) as f:
        header = f.readline().strip().split(",")
        rows = [[float(x) for x in line.split(",")] for line in f if line.strip()]
    return header, np.array(rows)


def same(a, b):
    """Bitwise equality (NaN equal to NaN)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    assert a.shape == b.shape, (a.shape, b.shape)
    diff = ~((a == b) | (np.isnan(a) & np.isnan(b)))
    assert not diff.any(), "%d entries differ, first at %s: %r vs %r" % (
        diff.sum(), np.argwhere(diff)[0], a[diff][0], b[diff][0])


MESHES = ["cow.off", "elephant.off", "elephant-with-holes.off"]


@pytest.fixture(scope="module", params=MESHES)
def mesh(request, meshes):
    path = os.path.join(meshes, request.param)
    V, F = lapmesh.read_mesh(path)
    return path, V, F


def test_read_mesh_matches_file(mesh, tmp_path):
    path, V, F = mesh
    assert V.dtype == np.float64 and V.shape[1] == 3 and F.dtype == np.int64 and F.shape[1] == 3
    V0, _ = read_off(path)
    same(V, V0)
    out = str(tmp_path / "copy.off")
    lapmesh.write_mesh(out, V, F)
    V1, F1 = read_off(out)
    same(V1, V)
    assert np.array_equal(F1, F)


@pytest.mark.parametrize("laplacian,area", [(None, None), ("cotangent", "mixed"), ("uniform", "barycentric")])
def test_curvatures_equal_cli_csv(mesh, cli, tmp_path, laplacian, area):
    path, V, F = mesh
    out = tmp_path / "c.csv"
    args = ["curvature", path, "-o", out, "-q"]
    kwargs = {}
    if laplacian:
        args += ["--laplacian", laplacian, "--area", area]
        kwargs = dict(laplacian=laplacian, area=area)
    cli(*args)
    header, table = read_csv(out)
    assert header == ["vertex", "mean", "gaussian", "k1", "k2"]
    c = lapmesh.curvatures(V, F, **kwargs)
    same(table[:, 0], np.arange(len(V)))
    for column, name in enumerate(header[1:], start=1):
        same(getattr(c, name), table[:, column])
    assert c.normal.shape == (len(V), 3) and c.area.shape == (len(V),)


def test_spectrum_and_reconstruction_equal_cli(mesh, cli, tmp_path):
    path, V, F = mesh
    basis = lapmesh.SpectralBasis(V, F, k=30)
    assert len(basis) >= 30 and basis.k == 30 and basis.vectors.shape == (len(V), len(basis))
    cli("spectrum", path, "-o", tmp_path / "s.csv", "-k", 30, "-q")
    header, table = read_csv(tmp_path / "s.csv")
    assert header == ["index", "eigenvalue"]
    same(basis.values[:30], table[:, 1])
    for k in (5, 10, 30):
        out = tmp_path / ("r%d.off" % k)
        cli("reconstruct", path, "-o", out, "-k", k, "--basis-size", 30, "-q")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", lapmesh.LapmeshWarning)
            Vk = basis.reconstruct(k)
        same(Vk, read_off(out)[0])
    # project: the coefficients rebuild the reconstruction
    C = basis.project(V, 10)
    assert C.shape == (10, 3)
    assert np.allclose(basis.vectors[:, :10] @ C, basis.reconstruct(10), rtol=0, atol=1e-9 * np.abs(V).max())
    c1 = basis.project(V[:, 0], 10)  # one column: another BLAS path, the same values to rounding
    assert c1.shape == (10,) and np.allclose(c1, C[:, 0], rtol=1e-12, atol=1e-12 * np.abs(C).max())


def test_basis_files_shared_with_cli(meshes, cli, tmp_path):
    path = os.path.join(meshes, "cow.off")
    V, F = lapmesh.read_mesh(path)
    cli("reconstruct", path, "-o", tmp_path / "a.off", "-k", 8, "--basis-size", 12, "--save-basis", tmp_path / "cli.basis", "-q")
    loaded = lapmesh.SpectralBasis.load(str(tmp_path / "cli.basis"), V, F)
    same(loaded.reconstruct(8), read_off(tmp_path / "a.off")[0])
    basis = lapmesh.SpectralBasis(V, F, k=12)
    same(basis.values, loaded.values)
    basis.save(str(tmp_path / "py.basis"))
    cli("reconstruct", path, "-o", tmp_path / "b.off", "-k", 12, "--load-basis", tmp_path / "py.basis", "-q")
    same(basis.reconstruct(12), read_off(tmp_path / "b.off")[0])
    bare = lapmesh.SpectralBasis.load(str(tmp_path / "py.basis"))
    same(bare.vectors, basis.vectors)
    assert bare.laplacian == basis.laplacian and bare.area == basis.area
    with pytest.raises(ValueError, match="without its mesh"):
        bare.reconstruct(3)


SMOOTH_CASES = [
    dict(scheme="implicit", lam="auto", iterations=3),
    dict(scheme="explicit", lam="auto", iterations=5),
    dict(scheme="explicit", lam=0.5, lambda_unit="bound", iterations=4, laplacian="uniform"),
    dict(scheme="conformal", lam=1.0, lambda_unit="edge2", iterations=2, area="mixed"),
    dict(scheme="implicit", lam=2.0, lambda_unit="edge2", iterations=2, fixed_operator=True, restore_volume=True),
    dict(scheme="implicit", lam="auto", iterations=2, fix_boundary=False),
]


def cli_smooth_args(case):
    args = ["--scheme", case["scheme"], "--lambda", case["lam"], "--iterations", case["iterations"]]
    for key in ("lambda_unit", "laplacian", "area"):
        if key in case:
            args += ["--" + key.replace("_", "-"), case[key]]
    for key in ("fixed_operator", "restore_volume"):
        if case.get(key):
            args.append("--" + key.replace("_", "-"))
    if case.get("fix_boundary") is False:
        args.append("--free-boundary")
    return args


@pytest.mark.parametrize("case", SMOOTH_CASES, ids=lambda c: "-".join("%s=%s" % kv for kv in c.items()))
def test_smooth_equals_cli(mesh, cli, tmp_path, case):
    path, V, F = mesh
    out = tmp_path / "s.off"
    r = subprocess.run([cli.path, "smooth", path, "-o", str(out), *map(str, cli_smooth_args(case)), "-q"],
                       capture_output=True, text=True, env=cli.env)
    if r.returncode != 0:  # e.g. restore_volume on a mesh with holes: the binding refuses it too
        with pytest.raises(ValueError) as e:  # ParameterError, MeshError or the library's invalid_argument
            lapmesh.smooth(V, F, **case)
        assert str(e.value).split(": ")[-1] in r.stderr, (str(e.value), r.stderr)
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lapmesh.LapmeshWarning)
        V2, report = lapmesh.smooth(V, F, **case)
    same(V2, read_off(out)[0])
    assert report["iterations"] == case["iterations"] and report["lambda"] > 0
    assert math.isnan(report["stability_bound"]) == (case["scheme"] != "explicit")
    assert isinstance(report["warnings"], list)


@pytest.mark.parametrize("options", [dict(level=0.05, seed=7), dict(level=0.01, seed=2**40 + 3, direction="normal", scale="bbox")])
def test_noise_equals_cli(mesh, cli, tmp_path, options):
    path, V, F = mesh
    out = tmp_path / "n.off"
    args = ["--level", options["level"], "--seed", options["seed"]]
    for key in ("direction", "scale"):
        if key in options:
            args += ["--" + key, options[key]]
    cli("noise", path, "-o", out, *args, "-q")
    same(lapmesh.add_noise(V, F, **options), read_off(out)[0])


def test_denoise_study_equals_cli(meshes, cli, tmp_path):
    import csv

    path = os.path.join(meshes, "head.off")
    V, F = lapmesh.read_mesh(path)
    cli("denoise-study", path, "-o", tmp_path / "s.csv", "--levels", "0,0.05", "--schemes", "explicit,implicit",
        "--laplacians", "uniform,cotangent", "--lambdas", "0.1,3", "--iterations", 3, "--seed", 5, "-q", "--no-progress")
    with open(tmp_path / "s.csv") as f:
        rows = list(csv.DictReader(f))
    r = lapmesh.denoise_study(V, F, levels=[0, 0.05], lambdas=[0.1, 3], iterations=3, seed=5)
    assert len(rows) == len(r["iteration"]) == 2 * 2 * 2 * 2 * 4
    unit = re.search(r"lambda_unit: str = '([\w-]+)'", lapmesh.denoise_study.__doc__).group(1)  # its default
    columns = {"noise_level": "noise_level", "sigma": "sigma", "time_step": "lambda_" + unit, "lambda": "lambda",
               "stability_bound": "stability_bound", "rms_distance": "rms_distance",
               "hausdorff_distance": "hausdorff_distance", "normal_angle_error": "normal_angle_error_deg",
               "volume_change": "volume_change"}
    for key, name in columns.items():
        same(r[key], [float(row[name]) for row in rows])
    assert list(r["iteration"]) == [int(row["iteration"]) for row in rows]
    for key in ("scheme", "laplacian", "status"):
        assert r[key] == [row[key] for row in rows]
    assert r["error"] == [row["error"] for row in rows]
    assert list(r["hausdorff_coarsening"]) == [1.0] * len(rows)
    with pytest.raises(lapmesh.ParameterError) as e:
        lapmesh.denoise_study(V, F, lambdas=[0.1, -1])
    assert e.value.parameter == "lambdas"
    with pytest.raises(lapmesh.ParameterError) as e:
        lapmesh.denoise_study(V, F, schemes=["implicit", "fast"])
    assert e.value.parameter == "schemes"


def test_denoise_study_says_how_much_the_hausdorff_grid_was_coarsened(meshes, cli, tmp_path):
    # A spacing far below the edge length would hold more than 16 samples per corner: the grid is
    # coarsened, by the factor that the command line reports for the same study.
    path = os.path.join(meshes, "head.off")
    V, F = lapmesh.read_mesh(path)
    options = dict(levels=[0.05], schemes=["explicit"], laplacians=["uniform"], lambdas=[0.5], iterations=1)
    r = lapmesh.denoise_study(V, F, hausdorff_spacing=1e-5, **options)
    largest = max(r["hausdorff_coarsening"])
    assert 1000 < largest < 20000  # about 5300: on a mesh this small the grid keeps about 2^20 samples
    assert min(r["hausdorff_coarsening"]) >= 1
    said = cli("denoise-study", path, "-o", tmp_path / "s.csv", "--levels", "0.05", "--schemes", "explicit",
               "--laplacians", "uniform", "--lambdas", "0.5", "--iterations", 1, "--hausdorff-spacing", "1e-5",
               "--no-progress").stdout
    reported = float(re.search(r"coarsened, up to ([0-9.e+]+) times", said).group(1))
    assert reported == pytest.approx(largest, rel=1e-5)  # the line prints six digits
    assert max(lapmesh.denoise_study(V, F, **options)["hausdorff_coarsening"]) == 1.0


def test_laplacian_matrix(mesh):
    scipy_sparse = pytest.importorskip("scipy.sparse")  # a skip fails the run (conftest)
    path, V, F = mesh
    S, M = lapmesh.laplacian(V, F)
    n = len(V)
    assert isinstance(S, scipy_sparse.csr_matrix) and S.shape == (n, n)
    scale = abs(S).max()
    assert abs(S - S.T).max() <= 1e-14 * scale
    assert np.abs(S @ np.ones(n)).max() <= 1e-12 * scale
    assert (S.diagonal() <= 0).all()
    e1, e2 = V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]
    surface = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1).sum()
    assert M.sum() == pytest.approx(surface, rel=1e-12)
    # L = M^-1 S is the curvature's Laplacian of the positions
    c = lapmesh.curvatures(V, F)
    assert np.allclose((S @ V) / M[:, None], c.laplacian, rtol=0, atol=1e-10 * np.abs(c.laplacian).max())
    # the uniform pencil: adjacency minus degrees, degrees as mass
    W, D = lapmesh.laplacian(V, F, laplacian="uniform")
    same(D, -W.diagonal())
    assert set(np.unique(W.data)) <= {1.0} | set(-D)
    data, indices, indptr, n2, mass = lapmesh.laplacian_arrays(V, F)
    same(data, S.data)
    same(mass, M)
    assert n2 == n
    # the assembly's own arrays, not copies: int32 indices, owned by the matrix they came from
    assert indices.dtype == np.int32 and indptr.dtype == np.int32 and data.dtype == np.float64
    assert not data.flags.owndata and not indices.flags.owndata and not indptr.flags.owndata
    assert (indices == S.indices).all() and (indptr == S.indptr).all()
    assert abs(S - S.T).max() == 0


def test_names_are_the_cli_choices(cli):
    for cmd, option, kind in [("curvature", "--laplacian", "laplacian"), ("curvature", "--area", "area"),
                              ("smooth", "--scheme", "scheme"), ("smooth", "--lambda-unit", "lambda_unit"),
                              ("noise", "--direction", "direction"), ("noise", "--scale", "scale")]:
        help_text = cli(cmd, "--help").stdout
        line = next(l for l in help_text.splitlines() if l.strip().startswith(option))
        assert "{" + ",".join(lapmesh.names(kind)) + "}" in line, (line, lapmesh.names(kind))
        # the default the CLI shows is the binding's
        if "[" in line:
            default = line.split("[")[1].split("]")[0]
            fn = {"curvature": lapmesh.curvatures, "smooth": lapmesh.smooth, "noise": lapmesh.add_noise}[cmd]
            assert "%s: str = '%s'" % (kind, default) in fn.__doc__, (kind, default, fn.__doc__.splitlines()[0])


def test_docstrings_and_stub():
    for f in (lapmesh.read_mesh, lapmesh.curvatures, lapmesh.smooth, lapmesh.add_noise, lapmesh.SpectralBasis,
              lapmesh.laplacian):
        assert f.__doc__ and len(f.__doc__) > 40
    stub = os.path.join(os.path.dirname(lapmesh.__file__), "__init__.pyi")
    assert os.path.exists(stub)
    text = open(stub).read()
    for name in lapmesh.__all__:
        assert (" %s(" % name) in text or ("class %s" % name) in text, name


def test_array_types_and_layouts(meshes):
    V, F = lapmesh.read_mesh(os.path.join(meshes, "cow.off"))
    c = lapmesh.curvatures(V, F)
    for V2, F2 in [(np.asfortranarray(V), F.astype(np.int32)), (V.tolist(), F.tolist()),
                   (np.hstack([V, V])[:, :3], F.astype(np.uint32))]:
        same(lapmesh.curvatures(V2, F2).mean, c.mean)


def test_repairs_are_warnings(meshes):
    with pytest.warns(lapmesh.LapmeshWarning, match="triangulated 6 polygon"):
        V, F = lapmesh.read_mesh(os.path.join(meshes, "cube_quad.off"))
    assert F.shape == (12, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a consistent triangle mesh gives no warning
        lapmesh.curvatures(V, F)


def test_mesh_object_gives_the_same_results(meshes, tmp_path):
    path = os.path.join(meshes, "cow.off")
    V, F = lapmesh.read_mesh(path)
    mesh = lapmesh.Mesh(V, F)
    assert (mesh.num_vertices, mesh.num_faces) == (len(V), len(F)) and "2904 vertices" in repr(mesh)
    same(mesh.V, V)
    assert np.array_equal(mesh.F, F)
    read = lapmesh.Mesh.read(path)
    same(read.V, V)
    same(lapmesh.curvatures(mesh, area="mixed").gaussian, lapmesh.curvatures(V, F, area="mixed").gaussian)
    same(lapmesh.smooth(mesh, iterations=2)[0], lapmesh.smooth(V, F, iterations=2)[0])
    same(lapmesh.add_noise(mesh, level=0.1, seed=3), lapmesh.add_noise(V, F, level=0.1, seed=3))
    same(lapmesh.laplacian(mesh)[0].data, lapmesh.laplacian(V, F)[0].data)
    basis = lapmesh.SpectralBasis(mesh, 8)
    same(basis.values, lapmesh.SpectralBasis(V, F, k=8).values)
    same(lapmesh.SpectralBasis(mesh, k=8).reconstruct(8), basis.reconstruct(8))
    basis.save(str(tmp_path / "b"))
    same(lapmesh.SpectralBasis.load(str(tmp_path / "b"), mesh).reconstruct(5), basis.reconstruct(5))
    with pytest.raises(TypeError, match="not both"):
        lapmesh.curvatures(mesh, F)
    with pytest.raises(TypeError, match="F is missing"):
        lapmesh.curvatures(V)
    with pytest.raises(TypeError, match="k is missing"):
        lapmesh.SpectralBasis(mesh)
    bad = V.copy()
    bad[3, 0] = np.inf
    with pytest.raises(lapmesh.MeshError):
        lapmesh.Mesh(bad, F)


# glibc's thresholds, set on import (src/operations/heap.h). An 8 MiB block is mapped apart
# (mallinfo2's hblks counts such blocks) under glibc's initial thresholds, and comes from the heap
# once the mmap threshold is 32 MiB. Each case runs in a fresh interpreter, whose allocator no
# earlier test has moved.
_HEAP_PROBE = """
import ctypes, sys
class Mallinfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks", "keepcost")]
libc = ctypes.CDLL(None)
libc.mallinfo2.restype = Mallinfo2
libc.malloc.restype = ctypes.c_void_p
libc.free.argtypes = [ctypes.c_void_p]
if sys.argv[1] == "import":
    import lapmesh
before = libc.mallinfo2().hblks
block = libc.malloc(8 << 20)
print(libc.mallinfo2().hblks - before)
libc.free(block)
"""


def test_import_keeps_the_heap_between_calls():
    def mapped_apart(*args, **variables):
        env = {k: v for k, v in os.environ.items() if k != "GLIBC_TUNABLES" and not k.startswith("MALLOC_")}
        env.update(variables)
        out = subprocess.run([sys.executable, "-c", _HEAP_PROBE, *args], env=env, check=True, capture_output=True,
                             text=True)
        return int(out.stdout.strip())

    assert mapped_apart("plain") == 1  # glibc's initial threshold: the probe can tell
    assert mapped_apart("import") == 0
    # A threshold the environment sets is left as it is.
    assert mapped_apart("import", GLIBC_TUNABLES="glibc.malloc.mmap_threshold=131072") == 1
    assert mapped_apart("import", MALLOC_MMAP_THRESHOLD_="131072") == 1


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="working arrays are mapped apart on Linux only")
def test_working_memory_is_kept_for_the_next_call_and_handed_back_on_request():
    V, F = torus(500, 300)  # 150k vertices: working arrays of 4 MiB and more
    lapmesh.release_working_memory()
    assert lapmesh.cached_working_memory() == 0
    first = lapmesh.curvatures(V, F)
    kept = lapmesh.cached_working_memory()
    assert kept >= 4 << 20
    # The next call takes its arrays from the cache and gives them back: the same amount, the same result.
    again = lapmesh.curvatures(V, F)
    assert lapmesh.cached_working_memory() == kept
    assert np.array_equal(again.mean, first.mean)
    assert lapmesh.release_working_memory() == kept
    assert lapmesh.cached_working_memory() == 0
