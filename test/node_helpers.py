"""Driving ``vibration_node`` by hand in tests: a fake wall clock, a node that does not step
on its own, one wake-up of its stepping thread. Shared by the node's test files (rclpy is
imported when a node is made, so a module that imports these still collects without it)."""


class FakeClock:
    """Wall clock the test advances by hand (s)."""

    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


def make_node(ctx, scene='sdof', overrides=(), clock=None, name='vibration_node', **params):
    """A ``VibrationNode`` on ``ctx`` that does not start its stepping thread, on ``clock``
    (default a new :class:`FakeClock`), with ``scene``, scene ``overrides`` and parameters."""
    from rclpy.parameter import Parameter

    from impact_damper_sim.ros.vibration_node import VibrationNode
    overrides_param = [Parameter('overrides', value=list(overrides))] if overrides else []
    return VibrationNode(
        name, context=ctx, start_stepping=False, clock=clock or FakeClock(),
        parameter_overrides=[Parameter('scene', value=scene), *overrides_param,
                             *[Parameter(k, value=v) for k, v in params.items()]])


def wake(node):
    """One wake-up of the stepping thread: its cycles until one asks to sleep (s)."""
    for _ in range(100):
        delay = node._cycle()
        if delay > 0:
            return delay
    raise AssertionError('the stepping thread never sleeps')


def call_service(executor, client, request, timeout=60.0, resend=2.0):
    """Call a service and spin ``executor`` until the answer; send again every ``resend`` s.

    A request sent just after discovery can lose its answer: the service's response writer
    has not matched the client's reader yet (DDS discovers each endpoint on its own). Seen
    with one core kept busy: no answer within 5 s in 1 of 4 runs with a single send. For
    requests that may be repeated (a refused or repeated parameter set, a read).

    Parameters
    ----------
    executor : rclpy.executors.Executor
        Spins the client's node.
    client : rclpy.client.Client
    request
        The service's request.
    timeout : float
        Longest wait in all (s): a deadline for a loaded machine, not a figure.
    resend : float
        Wait for one answer before sending again (s).
    """
    import time
    assert client.wait_for_service(timeout_sec=timeout)
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        future = client.call_async(request)
        again = min(end, time.monotonic() + resend)
        while not future.done() and time.monotonic() < again:
            executor.spin_once(timeout_sec=0.01)
        if future.done():
            return future.result()
        client.remove_pending_request(future)
    raise AssertionError(f'no answer in {timeout:g} s')
