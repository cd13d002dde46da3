import numpy as np
import pytest
import warp as wp

wp.config.log_level = wp.LOG_WARNING
wp.init()

DEVICES = ["cpu"] + [d.alias for d in wp.get_cuda_devices()]


@pytest.fixture(params=DEVICES)
def device(request):
    """Every Warp device present: the CPU always, each CUDA device when there is one."""
    return request.param


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def polydisperse_scene(rng, n=150, extent=5.0, rmin=0.2, rmax=0.6):
    centers = rng.uniform(0.0, extent, (n, 3))
    radii = rng.uniform(rmin, rmax, n)
    return centers, radii
