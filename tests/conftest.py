"""Shared fixtures: the device fixture runs a test on the CPU always, and on CUDA when present;
the tests listed in tests/slow.txt are marked `slow` (`make test` skips them, `make test-all` runs all)."""

import os
from pathlib import Path

import pytest
import warp as wp

wp.config.log_level = wp.LOG_WARNING
wp.init()

# WARP_RICOCHET_TEST_DEVICES=cuda:0 limits the device tests (e.g. on a GPU host without Warp's CPU compiler)
DEVICES = (
    os.environ.get("WARP_RICOCHET_TEST_DEVICES", "").split(",")
    if os.environ.get("WARP_RICOCHET_TEST_DEVICES")
    else (["cpu"] + (["cuda:0"] if wp.is_cuda_available() else []))
)


@pytest.fixture(params=DEVICES)
def device(request):
    """Every test that takes `device` runs on the CPU, and on CUDA where a GPU exists."""
    return request.param


SLOW = {
    line.strip()
    for line in (Path(__file__).parent / "slow.txt").read_text().splitlines()
    if line.strip() and not line.startswith("#")
}


def pytest_collection_modifyitems(config, items):
    """Mark the node ids of tests/slow.txt `slow`."""
    for item in items:
        if item.nodeid in SLOW:
            item.add_marker(pytest.mark.slow)
