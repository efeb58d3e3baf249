"""The GIL is released while the library computes, and progress callbacks run (and can cancel)."""
import os
import threading
import time

import pytest

import lapmesh


@pytest.fixture(scope="module")
def cow(meshes):
    return lapmesh.read_mesh(os.path.join(meshes, "cow.off"))


def test_gil_released_during_computation(cow):
    V, F = cow
    done = threading.Event()
    spins = []

    def work():
        t = time.perf_counter()
        lapmesh.SpectralBasis(V, F, k=60)
        spins.append(time.perf_counter() - t)
        done.set()

    thread = threading.Thread(target=work)
    count = 0
    thread.start()
    while not done.is_set():  # runs only while the other thread does not hold the GIL
        count += 1
    thread.join()
    seconds = spins[0]
    # Holding the GIL, the computation would leave this loop a few switch intervals (5 ms) at most.
    assert count > 1000 and seconds > 0.02, (count, seconds)


def test_smooth_progress(cow):
    V, F = cow
    calls = []
    lapmesh.smooth(V, F, iterations=3, progress=lambda done, total: calls.append((done, total)))
    assert calls == [(1, 3), (2, 3), (3, 3)]


class Stop(Exception):
    pass


def test_progress_exception_cancels(cow):
    V, F = cow

    def stop(done, total):
        raise Stop("enough")

    with pytest.raises(Stop, match="enough"):
        lapmesh.smooth(V, F, iterations=3, progress=stop)
    stages = []

    def spectral(stage, solves, attempt, seconds):
        stages.append(stage)
        if len(stages) >= 1:
            raise Stop("cancelled")

    with pytest.raises(Stop):
        lapmesh.SpectralBasis(V, F, k=40, progress=spectral)
    assert stages
    with pytest.raises(TypeError):
        lapmesh.smooth(V, F, progress=3)
