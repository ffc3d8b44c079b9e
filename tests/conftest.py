"""Shared fixtures: the device fixture runs a test on the CPU always, and on CUDA when present."""

import pytest
import warp as wp

wp.config.log_level = wp.LOG_WARNING
wp.init()

DEVICES = ["cpu"] + (["cuda:0"] if wp.is_cuda_available() else [])


@pytest.fixture(params=DEVICES)
def device(request):
    """Every test that takes `device` runs on the CPU, and on CUDA where a GPU exists."""
    return request.param
