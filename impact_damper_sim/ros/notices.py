"""Start-up and graph notices: a slow start-up step's "still ..." lines, a name clash.

* :class:`BusyNotice` logs that a slow start-up step (loading and compiling) is still
  running.
* :class:`NameClash` warns when another node with the node's fully qualified name appears in
  the ROS graph.
* :class:`ThrottledLog` is a node's log with a throttle of its own per key.
"""
from __future__ import annotations

import math
import sys
import threading
import time


class ThrottledLog:
    """A node's log: ``log(level, text, throttle=None, key=None)`` logs ``text`` at ``level``
    (info, warning, error), at most once per ``throttle`` s per ``key``; to stderr once the
    context is gone (there is no rosout then). Our throttle, not rclpy's: rclpy's inspects
    the caller's frame on every call (2-6 ms).

    Parameters
    ----------
    node : rclpy.node.Node
        The node whose logger and context are used.
    """

    def __init__(self, node):
        self._node = node
        self._last = {}

    def __call__(self, level, text, throttle=None, key=None):
        node = self._node
        if throttle:
            now = time.monotonic()
            key = (level, key)
            if now - self._last.get(key, -math.inf) < throttle:
                return
            self._last[key] = now
        if not node.context.ok():
            print(f'[{level.upper()}] [{node.get_name()}]: {text}', file=sys.stderr)
            return
        logger = node.get_logger()   # one call site per severity (rclpy requires it)
        if level == 'info':
            logger.info(text)
        elif level == 'warning':
            logger.warning(text)
        else:
            logger.error(text)


class BusyNotice:
    """Logs, every ``period`` s until stopped, that a slow start-up step is still running."""

    def __init__(self, log, what, period=5.0):
        self._done = threading.Event()
        self._t0 = time.monotonic()

        def run():
            while not self._done.wait(period):
                log(f'still {what} ({time.monotonic() - self._t0:.0f} s)')

        self._thread = threading.Thread(target=run, name='startup_notice', daemon=True)
        self._thread.start()

    def stop(self):
        """Stop the notices; return the elapsed time (s)."""
        self._done.set()
        self._thread.join()
        return time.monotonic() - self._t0


class NameClash:
    """Warns, once each time it appears, of another node with this node's fully qualified
    name in the ROS graph (rclpy and DDS allow it and say nothing).

    Two such nodes both publish ``/clock`` (sim time then runs backwards for every
    subscriber: 385 times in 6 s, measured), and their parameters and services are
    ambiguous. Call it from a slow timer, never from the stepping thread: it reads the graph
    that discovery keeps (a few microseconds).

    Parameters
    ----------
    node : rclpy.node.Node
        The node.
    log : callable
        Called with the one-line warning (str).
    """

    def __init__(self, node, log):
        self._node, self._log = node, log
        self.clashing = False

    def __call__(self):
        """Look once; True while another node has this node's name."""
        node = self._node
        try:
            graph = node.get_node_names_and_namespaces()
        except Exception:   # the context is shutting down: no graph to read
            return self.clashing
        clashing = graph.count((node.get_name(), node.get_namespace())) > 1
        if clashing and not self.clashing:
            name = node.get_fully_qualified_name()
            self._log(f'another node in the ROS graph has this fully qualified name, {name}: '
                      'two nodes publishing /clock make sim time run backwards, and their '
                      f'parameters and services ({name}/record) are ambiguous; give one '
                      'another name (--ros-args -r __node:=<name>) or namespace '
                      '(-r __ns:=/<namespace>)')
        self.clashing = clashing
        return clashing


__all__ = ['BusyNotice', 'NameClash', 'ThrottledLog']
