"""Shared fixtures: a fresh rclpy context per test (the rclpy tests' pattern).

Each test gets its own ``rclpy.Context`` on its own DDS domain, so nodes of different tests
(and of other processes testing on this machine) never see each other. Discovery is kept on
this host (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``).
"""
import itertools
import os

import pytest

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

# domain ids 1..100, offset by the process id so that concurrent pytest runs differ
_DOMAINS = itertools.count(os.getpid() % 97)


def next_domain_id():
    """Return a DDS domain id (1..100) not used by an earlier test of this process."""
    return 1 + next(_DOMAINS) % 100


@pytest.fixture
def ros_context():
    """Yield an initialized ``rclpy.Context``; shut it down after the test."""
    rclpy = pytest.importorskip('rclpy')
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=next_domain_id())
    try:
        yield ctx
    finally:
        rclpy.try_shutdown(context=ctx)
