#!/usr/bin/env python3
"""The cost of the Python bindings at about 100,000 vertices: lapmesh.curvatures and
lapmesh.laplacian timed through the module and, with the same operations-layer calls, in C++
(the program lapmesh_overhead_cpp, built by `cmake --build build --target lapmesh_overhead_cpp`).

    PYTHONPATH=build/python python3 python/benchmarks/overhead.py [MESH] [--repeats R] [--cpp PATH]

MESH (default: CGAL's armadillo.off, 26,002 vertices) is subdivided once (each triangle into
four at its edge midpoints) and written to a temporary OFF file for the C++ program. Every time
is the best of R runs (default 5) in each of N rounds (--rounds, default 4) that
alternate the module and the C++ program, in seconds. A call on arrays (V, F) converts them to a polygon
soup and validates it into a mesh (lapmesh_ops::mesh_from_soup, as reading a file does); a call
on a lapmesh.Mesh skips both. Not a test: the figures depend on the machine and its load.

Both sides run with glibc's malloc told to keep freed memory (MALLOC_MMAP_THRESHOLD_,
MALLOC_TRIM_THRESHOLD_; the script restarts itself with them unless --default-malloc): with the
defaults, a call's large result vectors come from fresh pages or not depending on what the
process allocated before, and that alone changed a curvature call at 100k vertices by a factor
of 4 between the two processes. --cpu N pins both to one core (TBB then runs on one thread),
which makes the timings steadier on a loaded machine.
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

import lapmesh


def best_of(repeats, f):
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - start)
    return best


def subdivide(V, F):
    """Each triangle into four at its edge midpoints (orientation kept)."""
    edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    unique, inverse = np.unique(edges, axis=0, return_inverse=True)
    mid = len(V) + inverse.reshape(3, len(F)).T
    V2 = np.concatenate([V, (V[unique[:, 0]] + V[unique[:, 1]]) / 2])
    a, b, c = F.T
    ab, bc, ca = mid.T
    F2 = np.concatenate([np.stack(t, 1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    return V2, F2


def default_mesh():
    here = os.path.dirname(os.path.abspath(__file__))
    folder = os.environ.get("LAPMESH_MESHES") or os.path.join(here, "..", "..", "build", "cgal-data", "data", "meshes")
    return os.path.join(folder, "armadillo.off")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("mesh", nargs="?", default=default_mesh())
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--rounds", type=int, default=4)
    p.add_argument("--cpp", default=os.path.join(os.path.dirname(lapmesh.__file__), "..", "lapmesh_overhead_cpp"),
                   help="the C++ timer (default: next to the module in the build tree)")
    p.add_argument("--default-malloc", action="store_true", help="keep glibc malloc's default thresholds")
    p.add_argument("--cpu", type=int, default=None, help="pin this process and the C++ timer to this core")
    a = p.parse_args()
    r = a.repeats
    if not a.default_malloc and "MALLOC_MMAP_THRESHOLD_" not in os.environ:
        os.environ.update(MALLOC_MMAP_THRESHOLD_=str(2 ** 31 - 1), MALLOC_TRIM_THRESHOLD_=str(2 ** 31 - 1))
        os.execv(sys.executable, [sys.executable] + sys.argv)  # malloc reads them at start-up
    if a.cpu is not None:
        os.sched_setaffinity(0, {a.cpu})  # inherited by the C++ timer

    V, F = subdivide(*lapmesh.read_mesh(a.mesh))
    print("mesh: %s subdivided once: %d vertices, %d faces; best of %d runs x %d rounds" % (
        os.path.basename(a.mesh), len(V), len(F), r, a.rounds))
    print("load average before: %.2f %.2f %.2f; malloc thresholds: %s; cores: %s" % (
        os.getloadavg() + ("default" if a.default_malloc else "raised", sorted(os.sched_getaffinity(0)))))

    cpp = os.path.abspath(a.cpp)
    have_cpp = os.access(cpp, os.X_OK)
    if not have_cpp:
        print("no C++ timer at %s (cmake --build build --target lapmesh_overhead_cpp): C++ comparison skipped" % cpp)
    F32 = F.astype(np.int32)
    mesh = lapmesh.Mesh(V, F)
    calls = {
        "np.ascontiguousarray(V), (F)": lambda: (np.ascontiguousarray(V, dtype=np.float64),
                                                 np.ascontiguousarray(F, dtype=np.int64)),
        "Mesh(V, F)": lambda: lapmesh.Mesh(V, F),
        "Mesh(V, F int32)": lambda: lapmesh.Mesh(V, F32),
        "curvatures(V, F)": lambda: lapmesh.curvatures(V, F),
        "curvatures(mesh)": lambda: lapmesh.curvatures(mesh),
        "laplacian_arrays(mesh)": lambda: lapmesh.laplacian_arrays(mesh),
        "laplacian(mesh) (scipy CSR)": lambda: lapmesh.laplacian(mesh),
        "laplacian(V, F) (scipy CSR)": lambda: lapmesh.laplacian(V, F),
    }
    # Rounds alternate the two sides, so that a burst of load from elsewhere hits both alike;
    # each figure is the best over all rounds.
    t, c = {}, {}
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "subdivided.off")
        lapmesh.write_mesh(path, V, F)
        for _ in range(a.rounds):
            for name, f in calls.items():
                t[name] = min(t.get(name, float("inf")), best_of(r, f))
            if have_cpp:
                out = subprocess.run([cpp, path, str(r)], capture_output=True, text=True, check=True).stdout
                for line in out.splitlines():
                    name, value = line.split()
                    c[name] = min(c.get(name, float("inf")), float(value))
    for name, seconds in t.items():
        print("python  %-30s %.4f s" % (name, seconds))
    if not have_cpp:
        return 0
    assert int(c["vertices"]) == len(V)
    for name in ("soup_from_arrays", "mesh_from_soup", "curvature", "laplacian", "curvature_of_loaded_file",
                 "curvature_from_arrays", "laplacian_from_arrays"):
        print("C++     %-30s %.4f s" % (name, c[name]))

    def share(py, cxx):
        return "%.4f s vs %.4f s: %+.1f%%" % (py, cxx, 100.0 * (py - cxx) / cxx)

    arrays = c["soup_from_arrays"] + c["mesh_from_soup"]
    print("curvatures on a Mesh vs C++ curvature:                       " + share(t["curvatures(mesh)"], c["curvature"]))
    print("laplacian_arrays on a Mesh vs C++ laplacian:                 " + share(t["laplacian_arrays(mesh)"], c["laplacian"]))
    print("laplacian (scipy) on a Mesh vs C++ laplacian:                " + share(t["laplacian(mesh) (scipy CSR)"],
                                                                              c["laplacian"]))
    print("Mesh(V, F) vs C++ soup from arrays + soup->mesh:             " + share(t["Mesh(V, F)"], arrays))
    print("curvatures on (V, F) vs C++ arrays->soup->mesh->curvature:   " +
          share(t["curvatures(V, F)"], c["curvature_from_arrays"]))
    print("laplacian (scipy) on (V, F) vs C++ arrays->soup->mesh->laplacian: " +
          share(t["laplacian(V, F) (scipy CSR)"], c["laplacian_from_arrays"]))
    print("load average after: %.2f %.2f %.2f" % os.getloadavg())
    return 0


if __name__ == "__main__":
    sys.exit(main())
