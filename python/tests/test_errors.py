"""Bad inputs raise the right exception, with a clear message, and never crash the interpreter."""
import os
import warnings

import numpy as np
import pytest

import lapmesh


@pytest.fixture(scope="module")
def cow(meshes):
    return lapmesh.read_mesh(os.path.join(meshes, "cow.off"))


def test_exception_hierarchy():
    assert issubclass(lapmesh.MeshError, ValueError)
    assert issubclass(lapmesh.ParameterError, ValueError)
    assert issubclass(lapmesh.NumericalError, RuntimeError)
    assert issubclass(lapmesh.IoError, OSError)
    assert issubclass(lapmesh.LapmeshWarning, UserWarning)


def test_nan_coordinate(cow):
    V, F = cow
    V = V.copy()
    V[17, 1] = np.nan
    with pytest.raises(lapmesh.MeshError) as e:
        lapmesh.curvatures(V, F)
    assert e.value.element == "vertex" and e.value.index == 17
    assert "17" in str(e.value)


@pytest.mark.parametrize("bad", [10**6, -1])
def test_index_out_of_range(cow, bad):
    V, F = cow
    F = F.copy()
    F[5, 2] = bad
    with pytest.raises(lapmesh.MeshError) as e:
        lapmesh.smooth(V, F)
    assert e.value.element == "face" and e.value.index == 5
    assert str(bad) in str(e.value)


def test_bad_shapes(cow):
    V, F = cow
    with pytest.raises(ValueError, match=r"V must be an array of shape \(n, 3\)"):
        lapmesh.curvatures(V[:, :2], F)
    with pytest.raises(ValueError, match=r"F must be an array of shape \(m, 3\)"):
        lapmesh.curvatures(V, F.ravel())
    with pytest.raises(TypeError):
        lapmesh.curvatures("not an array", F)


@pytest.mark.parametrize("value", [0.5, float("nan"), float("inf")])
def test_faces_as_floats_must_be_whole_numbers(cow, value):
    # Floats holding whole numbers (np.loadtxt's arrays) are indices; anything else is refused
    # instead of being truncated into another mesh.
    V, F = cow
    Ff = F.astype(float)
    assert np.array_equal(lapmesh.curvatures(V, Ff).mean, lapmesh.curvatures(V, F).mean)
    Ff[4, 1] = F[4, 1] + value
    for call in (lambda: lapmesh.curvatures(V, Ff), lambda: lapmesh.Mesh(V, Ff)):
        with pytest.raises(ValueError, match=r"F must hold whole vertex indices: F\[4, 1\] is "):
            call()


def test_faces_beyond_int64_and_odd_dtypes_are_refused(cow, tmp_path):
    V, F = cow
    Fu = F.astype(np.uint64)
    assert np.array_equal(lapmesh.curvatures(V, Fu).mean, lapmesh.curvatures(V, F).mean)
    Fu[2, 0] = np.uint64(2**64 - 1)  # int64's cast would make it -1
    with pytest.raises(ValueError, match=r"F\[2, 0\] is 18446744073709551615, beyond any vertex index"):
        lapmesh.smooth(V, Fu)
    with pytest.raises(ValueError, match=r"F\[2, 0\] is 18446744073709551615"):
        lapmesh.write_mesh(str(tmp_path / "u.off"), V, Fu)
    assert not os.path.exists(tmp_path / "u.off")
    with pytest.raises(TypeError, match="F must be an array of shape \\(m, 3\\) of integers, got dtype bool"):
        lapmesh.curvatures(V, F > 0)
    with pytest.raises(TypeError, match="V must be an array of shape \\(n, 3\\) of real numbers, got dtype complex128"):
        lapmesh.curvatures(V + 0j, F)
    # Arrays of Python numbers (dtype object) are taken as numbers, with the same checks.
    assert np.array_equal(lapmesh.curvatures(V.astype(object), F.astype(object)).mean, lapmesh.curvatures(V, F).mean)
    Fo = F.astype(object)
    Fo[3, 2] = 2.5
    with pytest.raises(ValueError, match=r"F must hold whole vertex indices: F\[3, 2\] is 2.5"):
        lapmesh.curvatures(V, Fo)
    basis = lapmesh.SpectralBasis(V, F, 5)
    assert np.array_equal(basis.project(V.astype(np.float32), 5), basis.project(V.astype(np.float32).astype(float), 5))
    with pytest.raises(TypeError, match="signal must be an array of shape .* of real numbers, got dtype complex128"):
        basis.project(V + 1j, 5)


@pytest.mark.parametrize("fn,kwargs", [
    (lapmesh.curvatures, dict(laplacian="cotan")),
    (lapmesh.curvatures, dict(area="circumcentric")),
    (lapmesh.smooth, dict(scheme="backward")),
    (lapmesh.smooth, dict(lambda_unit="edge")),
    (lapmesh.add_noise, dict(direction="tangent")),
    (lapmesh.laplacian, dict(laplacian="graph")),
])
def test_unknown_names(cow, fn, kwargs):
    V, F = cow
    (key, value), = kwargs.items()
    with pytest.raises(lapmesh.ParameterError) as e:
        fn(V, F, **kwargs)
    assert e.value.parameter == key
    message = str(e.value)
    assert repr(value) in message
    for name in lapmesh.names(key):
        assert name in message  # the accepted names are listed


@pytest.mark.parametrize("k", [0, -3, 2905])
def test_k_out_of_range(cow, k):
    V, F = cow
    with pytest.raises(lapmesh.ParameterError) as e:
        lapmesh.SpectralBasis(V, F, k)
    assert e.value.parameter == "k" and str(k) in str(e.value)


def test_basis_k_and_signal(cow):
    V, F = cow
    basis = lapmesh.SpectralBasis(V, F, k=4)
    for k in (0, len(basis) + 1):
        with pytest.raises(lapmesh.ParameterError) as e:
            basis.reconstruct(k)
        assert e.value.parameter == "k"
        with pytest.raises(lapmesh.ParameterError):
            basis.project(V, k)
    with pytest.raises(lapmesh.ParameterError) as e:
        basis.project(V[:10], 2)
    assert e.value.parameter == "signal"


@pytest.mark.parametrize("level", [-0.1, float("nan"), float("inf")])
def test_bad_noise_level(cow, level):
    V, F = cow
    with pytest.raises(lapmesh.ParameterError) as e:
        lapmesh.add_noise(V, F, level=level)
    assert e.value.parameter == "level"


@pytest.mark.parametrize("lam", [-1.0, 0, "fast", float("nan")])
def test_bad_time_step(cow, lam):
    V, F = cow
    with pytest.raises(lapmesh.ParameterError) as e:
        lapmesh.smooth(V, F, lam=lam)
    assert e.value.parameter == "lam" and str(e.value).startswith("lam: ")


def test_bad_iterations(cow):
    V, F = cow
    with pytest.raises(lapmesh.ParameterError) as e:
        lapmesh.smooth(V, F, iterations=0)
    assert e.value.parameter == "iterations"


def test_restore_area_with_boundary_suggests_free_boundary(meshes):
    V, F = lapmesh.read_mesh(os.path.join(meshes, "elephant-with-holes.off"))
    with pytest.raises(lapmesh.ParameterError) as e:
        lapmesh.smooth(V, F, restore_area=True)
    assert e.value.parameter == "fix_boundary" and e.value.suggested_value is False
    assert "fix_boundary=False" in str(e.value)


def test_explicit_above_bound_warns(cow):
    V, F = cow
    with pytest.warns(lapmesh.LapmeshWarning, match="stab") as w:
        V2, report = lapmesh.smooth(V, F, scheme="explicit", lam=1.5, lambda_unit="bound", iterations=1)
    assert report["warnings"] and report["above_stability_bound"]
    assert "(set lam='auto'" in str(w[0].message)  # the suggestions in Python's spelling


def test_io_errors(tmp_path, cow):
    V, F = cow
    missing = str(tmp_path / "missing.off")
    with pytest.raises(lapmesh.IoError, match="missing.off"):
        lapmesh.read_mesh(missing)
    bad = tmp_path / "bad.off"
    bad.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n")
    with pytest.raises(lapmesh.IoError, match="bad.off"):
        lapmesh.read_mesh(str(bad))
    with pytest.raises(lapmesh.IoError):
        lapmesh.write_mesh(str(tmp_path / "x.xyz"), V, F)
    with pytest.raises(lapmesh.IoError):
        lapmesh.write_mesh(str(tmp_path / "no" / "dir" / "x.off"), V, F)
    junk = tmp_path / "junk.basis"
    junk.write_bytes(b"LAPMSB01" + b"\x00" * 40)
    with pytest.raises(lapmesh.IoError, match="junk.basis"):
        lapmesh.SpectralBasis.load(str(junk))


def test_basis_of_another_mesh_is_refused(cow, meshes, tmp_path):
    V, F = cow
    basis = lapmesh.SpectralBasis(V, F, k=3)
    basis.save(str(tmp_path / "cow.basis"))
    V2 = V * 2.0
    with pytest.raises(lapmesh.ParameterError) as e:
        lapmesh.SpectralBasis.load(str(tmp_path / "cow.basis"), V2, F)
    assert e.value.parameter == "basis"


def test_degenerate_face(cow):
    V, F = cow
    F = F.copy()
    V = V.copy()
    V[F[3, 1]] = V[F[3, 0]]  # zero-area face
    with pytest.raises(lapmesh.MeshError):
        lapmesh.curvatures(V, F)


def test_write_mesh_checks_indices_not_geometry(cow, tmp_path):
    V, F = cow
    F2 = F.copy()
    F2[7, 0] = len(V)
    with pytest.raises(lapmesh.MeshError) as e:
        lapmesh.write_mesh(str(tmp_path / "x.off"), V, F2)
    assert e.value.element == "face" and e.value.index == 7
    V2 = V.copy()
    V2[F[0, 1]] = V2[F[0, 0]]  # a degenerate result is written as it is (as the CLI writes it)
    lapmesh.write_mesh(str(tmp_path / "d.off"), V2, F)
    assert os.path.getsize(tmp_path / "d.off") > 0


def test_defects_of_real_meshes_take_the_intrinsic_laplacian(cow):
    # A zero-area face, a third face on an edge, and a vertex in no face: the cotangent
    # Laplacian refuses the first two naming the intrinsic one, which takes all three.
    import scipy.sparse

    V, F = cow
    V = np.vstack([V, V[:1] + 5.0])  # the last vertex is in no face
    F = F.copy()
    V[F[3, 1]] = V[F[3, 0]]
    with pytest.raises(lapmesh.MeshError, match="intrinsic-delaunay"):
        lapmesh.curvatures(V, F)
    a, b = F[10, 0], F[10, 1]
    book = np.vstack([F, [[a, b, F[200, 2]]]])
    with pytest.raises(lapmesh.MeshError, match="non-manifold"):
        lapmesh.laplacian(V, book)
    c = lapmesh.curvatures(V, book, laplacian="intrinsic-delaunay")
    assert np.isnan(c.mean[-1]) and c.area[-1] == 0
    assert np.isfinite(c.mean[:-1]).all() and np.isfinite(c.gaussian[:-1]).all()
    mesh = lapmesh.Mesh(V, book)
    assert mesh.num_vertices == len(V)
    S, M = lapmesh.laplacian(mesh, laplacian="intrinsic-delaunay")
    assert S.shape == (len(V), len(V))
    off = S - scipy.sparse.diags(S.diagonal())
    assert off.min() >= -1e-12
    V2, _ = lapmesh.smooth(mesh, scheme="implicit", lam="auto", iterations=2, laplacian="intrinsic-delaunay")
    assert (V2[-1] == V[-1]).all() and np.isfinite(V2).all()
    # The mollification margin is a keyword: 0 leaves the zero-area face's angles undefined.
    c0 = lapmesh.curvatures(V, F, laplacian="intrinsic-delaunay", mollification=1e-3)
    assert np.isfinite(c0.mean[:-1]).all()
    with pytest.raises(lapmesh.ParameterError) as e:
        lapmesh.curvatures(V, F, laplacian="intrinsic-delaunay", mollification=-1.0)
    assert e.value.parameter == "mollification"
    study = dict(levels=[0.05], schemes=["implicit"], laplacians=["intrinsic-delaunay"], lambdas=[1.0],
                 iterations=1)
    rms = [lapmesh.denoise_study(V, F, mollification=m, **study)["rms_distance"][-1] for m in (1e-5, 0.05)]
    assert np.isfinite(rms).all() and abs(rms[0] - rms[1]) > 1e-9
    with pytest.raises(lapmesh.ParameterError) as e:
        lapmesh.denoise_study(V, F, mollification=2.0, **study)
    assert e.value.parameter == "mollification"


def test_component_shrunk_to_a_point_is_held_and_warned(meshes):
    V, F = lapmesh.read_mesh(os.path.join(meshes, "sphere.off"))
    V = V - V.mean(axis=0)
    V = V / np.linalg.norm(V, axis=1).max()
    # A unit sphere and a copy of radius 0.01 beside it, as one mesh of two components.
    V2 = np.vstack([V, 0.01 * V + [3.0, 0.0, 0.0]])
    F2 = np.vstack([F, F + len(V)])
    with pytest.warns(lapmesh.LapmeshWarning, match="held there") as w:
        S, report = lapmesh.smooth(V2, F2, scheme="implicit", lam=0.01, lambda_unit="absolute", iterations=6)
    assert "(set fixed_operator=True)" in str(w[0].message)
    assert report["iterations"] == 6
    [held] = report["collapsed_components"]
    assert held["first_vertex"] == len(V) and held["vertices"] == len(V)
    assert 1 <= held["iteration"] <= 6 and held["area_over_lambda"] < 1e-12
    # The large sphere's run is the one it takes alone.
    alone, _ = lapmesh.smooth(V, F, scheme="implicit", lam=0.01, lambda_unit="absolute", iterations=6)
    assert np.abs(S[: len(V)] - alone).max() < 1e-12
    # In the denoising study the same flow's steps from the hold on are `held`, naming it.
    study = lapmesh.denoise_study(V2, F2, levels=[0.0], schemes=["implicit"], laplacians=["cotangent"],
                                  lambdas=[0.01], lambda_unit="absolute", iterations=6)
    since = held["iteration"]
    assert study["status"] == ["ok"] * since + ["held"] * (7 - since)
    reason = "held: the connected component of vertex %d (%d vertices) since iteration %d" % (len(V), len(V), since)
    assert study["error"] == [""] * since + [reason] * (7 - since)
    assert np.isfinite(study["rms_distance"]).all()
