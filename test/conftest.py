"""Shared fixtures: a fresh rclpy Context per test on its own DDS domain, data paths."""
import itertools
import os
import time
from pathlib import Path

import pytest

# Keep DDS discovery on this machine; each test also gets its own domain id.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / 'shared' / 'data'
_domain_ids = itertools.count()


def next_domain_id():
    """A domain id unlikely to be used by a concurrent test run (1..200)."""
    return 1 + (os.getpid() * 7 + next(_domain_ids)) % 200


@pytest.fixture
def domain_id():
    """A distinct ROS_DOMAIN_ID for this test."""
    return next_domain_id()


@pytest.fixture
def ros_context(domain_id):
    """An initialised rclpy Context on its own domain, shut down after the test."""
    rclpy = pytest.importorskip('rclpy')
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    try:
        yield ctx
    finally:
        ctx.try_shutdown()


def spin_until(executor, predicate, timeout_s):
    """Spin ``executor`` until ``predicate()`` is true or ``timeout_s`` of wall time pass."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if predicate():
            return True
        executor.spin_once(timeout_sec=0.05)
    return predicate()


def shared_data(name):
    """Path of a recording in ../shared/data, or skip the test with the reason."""
    p = SHARED_DATA / name
    if not p.exists():
        pytest.skip(f'{p} not present (../shared/data is not beside the checkout)')
    return p
