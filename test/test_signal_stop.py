"""A node process ends on a signal without hanging (CI: a plant's node ignored SIGINT and
SIGTERM for 15 s and ``ros2 launch`` SIGKILLed it).

The cause, shown in a child process: Python's default SIGINT handler raises
``KeyboardInterrupt`` in the main thread one bytecode after its wait for the node's lock
succeeds, when the signal reached another thread, and the lock is never released.
:class:`~impact_damper_sim.ros.process.SignalStop` only notes the signal once the node runs;
:meth:`VibrationNode.stop` waits for its stepping thread at most ``STOP_WAIT`` and says where
it is stuck."""
import subprocess
import sys
import textwrap
import threading
import time

import pytest

from node_helpers import make_node

# A holder thread takes the lock, waits until the main thread waits for it, signals SIGINT to
# itself (so the main thread's wait is not interrupted), then releases it.
_RACE = textwrap.dedent('''
    import signal, sys, threading, time
    from impact_damper_sim.ros.handoff import HandoffLock
    if sys.argv[1] == 'signal_stop':
        from impact_damper_sim.ros.process import SignalStop
        stop = SignalStop()
        stop.begin_running()
    lock, held = HandoffLock(), threading.Event()

    def holder():
        with lock:
            held.set()
            deadline = time.monotonic() + 60.0
            while lock.waiting == 0 and time.monotonic() < deadline:
                time.sleep(0.001)   # until the main thread counts itself a waiter
            time.sleep(0.05)   # and is inside the lock's acquire
            signal.pthread_kill(threading.get_ident(), signal.SIGINT)
            time.sleep(0.2)

    thread = threading.Thread(target=holder)
    thread.start()
    held.wait()
    outcome = 'released'
    try:
        with lock:
            time.sleep(0.05)
    except KeyboardInterrupt:
        outcome = 'interrupted'
    thread.join()
    taken = []
    other = threading.Thread(target=lambda: taken.append(lock._lock.acquire(timeout=1.0)))
    other.start()
    other.join()
    noted = stop.signum == signal.SIGINT if sys.argv[1] == 'signal_stop' else None
    print(outcome, 'free' if taken[0] else 'leaked', noted, lock.waiting)
''')


@pytest.mark.parametrize('handler, expected', [
    ('python_default', 'interrupted leaked None 0'),   # the hang's cause: the test can fail
    ('signal_stop', 'released free True 0'),
])
def test_a_sigint_on_another_thread_leaks_the_lock_only_without_signal_stop(handler, expected):
    """Default handler: ``KeyboardInterrupt`` after the lock was taken, the lock leaked (no
    other thread can take it in 1 s). With SignalStop running: no exception, the lock free,
    the signal noted, no waiter left counted."""
    out = subprocess.run([sys.executable, '-c', _RACE, handler], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split('\n')[0] == expected, out.stdout + out.stderr


def test_signal_stop_raises_while_the_node_is_built_and_notes_once_it_runs():
    """Before ``begin_running`` SIGINT raises (Ctrl-C cuts a long start-up short); a SIGTERM
    then is kept and ends the start-up at ``begin_running``; after it nothing raises."""
    script = textwrap.dedent('''
        import signal
        from rclpy.executors import ExternalShutdownException
        from impact_damper_sim.ros.process import SignalStop
        stop = SignalStop()
        try:
            signal.raise_signal(signal.SIGINT)
            print('no raise')
        except KeyboardInterrupt:
            print('raised')
        stop = SignalStop()
        signal.raise_signal(signal.SIGTERM)
        try:
            stop.begin_running()
        except ExternalShutdownException:
            print('ends at begin_running', stop.signum == signal.SIGTERM)
        stop = SignalStop()
        stop.begin_running()
        signal.raise_signal(signal.SIGINT)
        signal.raise_signal(signal.SIGTERM)
        print('noted', stop.signum == signal.SIGINT)
    ''')
    out = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split('\n')[:3] == ['raised', 'ends at begin_running True',
                                          'noted True'], out.stdout + out.stderr


def test_stop_gives_up_on_a_stuck_stepping_thread_and_says_where_it_is(ros_context,
                                                                        monkeypatch):
    """A stepping thread waiting for a lock that is never released: ``stop`` returns after
    ``STOP_WAIT`` (0.3 s here) instead of waiting for ever, and logs at ERROR where the thread
    is (its wait in ``_cycle``). Released, the thread ends on its own."""
    from impact_damper_sim.ros.process import thread_stack
    node = make_node(ros_context, 'sdof')
    lines = []
    monkeypatch.setattr(node, '_log', lambda level, text, *a: lines.append((level, text)))
    node.STOP_WAIT = 0.3
    try:
        node._lock._lock.acquire()   # the leaked lock: held by this thread, never released
        node.start()
        thread = node._thread
        deadline = time.monotonic() + 30.0
        # the stepper's own waits are not counted (HandoffLock.stepper): read its stack
        while 'with self._lock' not in thread_stack(thread) and time.monotonic() < deadline:
            time.sleep(0.01)   # the stepping thread now waits for the lock
        assert 'with self._lock' in thread_stack(thread)
        start = time.monotonic()
        node.stop()
        waited = time.monotonic() - start
        assert 0.3 <= waited < 20.0   # STOP_WAIT, not for ever (a deadline on a loaded host)
        errors = [text for level, text in lines if level == 'error']
        assert len(errors) == 1 and 'did not stop within 0.3 s' in errors[0], lines
        assert 'in _cycle' in errors[0] and 'with self._lock' in errors[0], errors[0]
        assert thread.is_alive()
        node._lock._lock.release()
        thread.join(30.0)
        assert not thread.is_alive()   # it saw the stop once it had the lock
    finally:
        if node._lock._lock._is_owned():
            node._lock._lock.release()
        node._thread = None
        node.destroy_node()


def test_a_stuck_thread_stack_names_its_frames():
    """``thread_stack`` gives the innermost frames of another running thread, and says so
    when the thread has ended."""
    from impact_damper_sim.ros.process import thread_stack
    gate = threading.Event()

    def waiting_for_the_gate():
        gate.wait(30.0)

    thread = threading.Thread(target=waiting_for_the_gate)
    thread.start()
    time.sleep(0.05)
    try:
        assert 'waiting_for_the_gate' in thread_stack(thread)
    finally:
        gate.set()
        thread.join()
    assert 'the thread has ended' in thread_stack(thread)


def test_a_clean_up_that_hangs_prints_every_stack_and_one_that_ends_prints_none():
    """Armed at 0.3 s: a clean-up still sleeping prints every thread's stack on stderr
    (where it sleeps); one that reaches ``shutdown_quietly`` in time prints nothing."""
    script = textwrap.dedent('''
        import sys, time
        import rclpy
        from impact_damper_sim.ros.process import report_a_stuck_clean_up, shutdown_quietly

        def a_hanging_clean_up():
            time.sleep(1.5)

        rclpy.init()
        report_a_stuck_clean_up(0.3)
        if sys.argv[1] == 'hangs':
            a_hanging_clean_up()
        shutdown_quietly()
        time.sleep(0.6)   # past the deadline: a dump not cancelled would show
    ''')
    for case, dumped in (('hangs', True), ('ends', False)):
        out = subprocess.run([sys.executable, '-c', script, case], capture_output=True,
                             text=True, timeout=120)
        assert out.returncode == 0, out.stderr
        assert ('a_hanging_clean_up' in out.stderr) is dumped, (case, out.stderr)
        assert ('Timeout (0:00:00' in out.stderr) is dumped, (case, out.stderr)
