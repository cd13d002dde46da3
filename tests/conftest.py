import numpy as np
import pytest
import warp as wp
from helpers import CUDA_DEVICES, DEVICES

wp.config.log_level = wp.LOG_WARNING


@pytest.fixture(params=DEVICES)
def device(request):
    """Every Warp device present: the CPU always, each CUDA device when there is one."""
    return request.param


@pytest.fixture(params=CUDA_DEVICES or [None])
def cuda_device(request):
    """Each CUDA device present; the test is skipped where there is none."""
    if request.param is None:
        pytest.skip("needs a CUDA device")
    return request.param


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
