"""Fixtures of the lapmesh Python tests: the CLI binary and CGAL's meshes (from the
environment ctest sets), a rule that a skipped test fails the run (a missing
dependency must not pass for a success), and a generated torus (`from conftest import torus`)."""
import os
import subprocess

import pytest


def _openblas_core_in_use():
    """The core whose kernels this process's OpenBLAS runs (the one under lapmesh's CHOLMOD),
    or None when the BLAS is another."""
    import ctypes

    import lapmesh  # noqa: F401  (loads CHOLMOD and its BLAS, libblas.so.3)

    try:
        corename = ctypes.CDLL("libblas.so.3").openblas_get_corename
    except (OSError, AttributeError):
        return None
    corename.restype = ctypes.c_char_p
    return corename().decode().strip() or None


# The environment the tests started with: the command line runs in it even after a Dask
# LocalCluster wrote its workers' settings (OMP_NUM_THREADS=1, ...) into os.environ, so that
# it uses as many BLAS threads as this process (the thread count changes the rounding). It
# also names the BLAS kernels this process runs: where OpenBLAS picked an old core's, the
# command line would otherwise restart with newer ones, which round differently.
START_ENVIRONMENT = dict(os.environ)
if "OPENBLAS_CORETYPE" not in START_ENVIRONMENT:
    _core = _openblas_core_in_use()
    if _core:
        START_ENVIRONMENT["OPENBLAS_CORETYPE"] = _core


def _required_env(name):
    value = os.environ.get(name)
    if not value:
        raise RuntimeError(name + " is not set: run these tests through ctest (ctest -R python)")
    return value


@pytest.fixture(scope="session")
def cli():
    path = _required_env("LAPMESH_CLI")
    assert os.access(path, os.X_OK), "the lapmesh command line is not built: " + path

    def run(*args):
        r = subprocess.run([path, *map(str, args)], capture_output=True, text=True, env=START_ENVIRONMENT)
        assert r.returncode == 0, "lapmesh %s failed: %s" % (" ".join(map(str, args)), r.stderr)
        return r

    run.path = path
    run.env = START_ENVIRONMENT
    return run


@pytest.fixture(scope="session")
def meshes():
    path = _required_env("LAPMESH_MESHES")
    assert os.path.exists(os.path.join(path, "cow.off")), "CGAL's data set is missing (install libcgal-demo): " + path
    return path


def pytest_configure(config):
    # tornado (under distributed) on Python 3.11: not lapmesh's to fix
    config.addinivalue_line("filterwarnings", "ignore:make_current is deprecated:DeprecationWarning")


def pytest_sessionfinish(session, exitstatus):
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None and reporter.stats.get("skipped") and session.exitstatus == 0:
        reporter.write_line("lapmesh: skipped tests count as failures (a dependency is missing)", red=True)
        session.exitstatus = 1


def torus(rings, segments):
    """A closed torus of rings x segments vertices."""
    import numpy as np

    u, v = np.meshgrid(np.arange(rings) * (2 * np.pi / rings), np.arange(segments) * (2 * np.pi / segments),
                       indexing="ij")
    V = np.stack([(2 + np.cos(v)) * np.cos(u), (2 + np.cos(v)) * np.sin(u), np.sin(v)], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(rings), np.arange(segments), indexing="ij")
    a, b = i * segments + j, ((i + 1) % rings) * segments + j
    c, d = ((i + 1) % rings) * segments + (j + 1) % segments, i * segments + (j + 1) % segments
    F = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return V, F
