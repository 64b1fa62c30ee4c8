"""What goes on the wire: publishers that serialize once, a vectorised ``Imu`` packer, guards.

* :class:`Outlet` publishes serialized bytes (rclpy sends ``bytes`` as they are) and gives
  the same bytes to the recorder, so a message is serialized once for both, by
  :func:`.cdr.serialize` (canonical CDR: zero pads, no trailing bytes, readable by rosbags).
* :class:`StampedPacker` (and :class:`ImuPacker`) writes a whole chunk of stamped messages
  (``sensor_msgs/Imu`` samples) as CDR in one NumPy pass from a canonical template; the field
  offsets are found in that template, and the packer checks a packed message against rclpy
  (a round trip) before it is used.
* :func:`guard_services` makes every service of a node answer (a refusal with the reason)
  instead of raising into the executor, which would stop the node.
* :func:`spin_guarded`, :func:`settle_interrupt` and :func:`shutdown_quietly` spin and end a
  ``main`` without racing rclpy's own SIGINT handler, which shuts the context down on another
  thread.
* :class:`HandoffLock` (the node's lock, handed over between chunks so that callbacks are not
  starved) and :class:`BusyNotice` (a start-up step's "still ..." log lines).
* :class:`NameClash` warns when another node with the node's fully qualified name appears in
  the ROS graph.
"""
from __future__ import annotations

import struct
import threading
import time

import numpy as np
from builtin_interfaces.msg import Time
from rclpy.serialization import deserialize_message

from .cdr import serialize


def type_name(msg_type):
    """``pkg/msg/Type`` of a generated message class (str)."""
    return f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}"


def stamp(t):
    """A ``builtin_interfaces/Time`` for sim time ``t`` (s)."""
    ns = int(round(t * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def set_stamp(header, t):
    """Set ``header.stamp`` to ``t`` (s) in place (cheaper than a new Time per message)."""
    ns = int(round(t * 1e9))
    header.stamp.sec, header.stamp.nanosec = divmod(ns, 1_000_000_000)


class Outlet:
    """A publisher that serializes a message once and gives the same bytes to the recorder.

    Parameters
    ----------
    node : rclpy.node.Node
        Owner; its ``_record(topic, type_name, qos, data, ns)`` receives every message.
    msg_type : type
        Message class.
    topic : str
        Topic name (relative names resolve in the node's namespace).
    qos : QoSProfile
        Offered QoS (also written to the record file).
    """

    def __init__(self, node, msg_type, topic, qos):
        self.pub = node.create_publisher(msg_type, topic, qos)
        self.topic = self.pub.topic_name   # fully qualified; cached (a C call each time)
        self.type_name = type_name(msg_type)
        self.msg_type = msg_type
        self.qos = qos
        self.count = 0   # messages published
        self._record = node._record

    def publish(self, msg, ns=None, wire=True):
        """Serialize ``msg`` once, publish (if ``wire``) and record the bytes (``ns``: log
        time, ns)."""
        self.publish_raw(serialize(msg), ns, wire)

    def publish_raw(self, data, ns=None, wire=True):
        """Publish (if ``wire``) and record serialized bytes ``data`` (``ns``: log time)."""
        if wire:
            self.pub.publish(data)
        self.count += 1
        self._record(self.topic, self.type_name, self.qos, data, ns)

    def has_subscribers(self):
        """bool: Some subscription is matched (DDS drops what nobody reads anyway)."""
        return self.pub.get_subscription_count() > 0


class StampedPacker:
    """Serializes chunks of one stamped message type that differ only in stamp and vectors.

    The message has a ``header`` and some ``geometry_msgs/Vector3`` fields (``paths``, e.g.
    ``('angular_velocity', 'linear_acceleration')`` of an ``Imu``); everything else is the
    template's. Offsets are found by serializing the template with sentinel values, and the
    packer checks a packed message against rclpy (a round trip) before it is used.

    Parameters
    ----------
    template : message
        Frame id and every other field of each message (copied now).
    paths : sequence of str
        Dotted paths of the Vector3 fields the chunks fill, in :meth:`pack`'s order.

    Raises
    ------
    RuntimeError
        The packed bytes do not deserialize to the message they should be (the CDR layout is
        not the one assumed); the caller then serializes message by message.
    """

    def __init__(self, template, paths):
        msg_type = type(template)
        self.paths = tuple(paths)
        probe = deserialize_message(serialize(template), msg_type)
        sentinels = [tuple(float(v) * (i + 1) * 1.0e-300 for v in (3.0, 7.0, 11.0))
                     for i in range(len(self.paths))]
        for path, values in zip(self.paths, sentinels):
            _set_vector(probe, path, values)
        probe.header.stamp.sec, probe.header.stamp.nanosec = 0x5EC0CAFE, 0x0DDBA11
        raw = serialize(probe)
        offsets = [raw.find(struct.pack('<3d', *values)) for values in sentinels]
        stamp_at = raw.find(struct.pack('<iI', 0x5EC0CAFE, 0x0DDBA11))
        if min(offsets + [stamp_at]) < 0 or raw[:2] != b'\x00\x01':   # little-endian CDR
            raise RuntimeError(f'{type_name(msg_type)}: unexpected CDR layout')
        self.size = len(raw)
        names = [f'v{i}' for i in range(len(self.paths))]
        self.dtype = np.dtype({'names': ['sec', 'nsec', *names],
                               'formats': ['<i4', '<u4'] + [('<f8', 3)] * len(names),
                               'offsets': [stamp_at, stamp_at + 4, *offsets],
                               'itemsize': self.size})
        self._names = names
        self._template = np.frombuffer(serialize(template), np.uint8).copy()
        # the round trip: a packed message must read back as the one rclpy would send
        check = deserialize_message(serialize(template), msg_type)
        check.header.stamp.sec, check.header.stamp.nanosec = 12, 345678901
        values = [(0.25 * (i + 1), -1.5e5, 2.0 ** -40) for i in range(len(self.paths))]
        for path, v in zip(self.paths, values):
            _set_vector(check, path, v)
        packed = self.pack(np.array([12_345_678_901]), *[np.array([v]) for v in values])[0]
        if len(packed) != self.size or deserialize_message(packed, msg_type) != check:
            raise RuntimeError(f'{type_name(msg_type)}: packed bytes do not read back')

    def pack(self, t_ns, *vectors):
        """Serialized messages (list of bytes), one per row.

        Parameters
        ----------
        t_ns : ndarray of int, shape (k,)
            Stamps (ns, >= 0).
        *vectors : ndarray, shape (k, 3)
            One array per path, in the units of that field.
        """
        k = len(t_ns)
        buf = np.empty(k, self.dtype)
        buf.view(np.uint8).reshape(k, self.size)[:] = self._template
        sec, nsec = np.divmod(np.asarray(t_ns, np.int64), 1_000_000_000)
        buf['sec'], buf['nsec'] = sec, nsec
        for name, values in zip(self._names, vectors):
            buf[name] = values
        raw = buf.tobytes()
        n = self.size
        return [raw[i:i + n] for i in range(0, k * n, n)]


def _set_vector(msg, path, values):
    target = msg
    for part in path.split('.'):
        target = getattr(target, part)
    target.x, target.y, target.z = values


class ImuPacker(StampedPacker):
    """A :class:`StampedPacker` of ``sensor_msgs/Imu``: ``pack(t_ns, linear_acceleration,
    angular_velocity)``."""

    def __init__(self, template):
        super().__init__(template, ('linear_acceleration', 'angular_velocity'))


def _refusal(request, response, reason):
    """Fill ``response`` as a refusal of ``request`` (every service type the node offers)."""
    from rcl_interfaces.msg import SetParametersResult
    if hasattr(response, 'results') and hasattr(request, 'parameters'):   # SetParameters
        response.results = [SetParametersResult(successful=False, reason=reason)
                            for _ in request.parameters]
    elif hasattr(response, 'result') and hasattr(request, 'parameters'):   # ...Atomically
        response.result = SetParametersResult(successful=False, reason=reason)
    elif hasattr(response, 'success') and hasattr(response, 'message'):   # SetBool, Trigger
        response.success, response.message = False, reason
    return response


def _unreadable(parameter_msg):
    """Why an ``rcl_interfaces/Parameter`` message cannot be read ('' if it can)."""
    from rclpy.parameter import Parameter
    try:
        Parameter.from_parameter_msg(parameter_msg)
    except Exception as exc:   # e.g. a type number that is no Parameter.Type
        return f'{parameter_msg.name}: refused: {type(exc).__name__}: {exc}'
    return ''


def _naming(node, parameter_msgs, reason):
    """``reason`` for refusing ``parameter_msgs``, prefixed with the names it is about when it
    names none of them (rclpy's own refusals: "Wrong parameter type...", "Static parameter
    cannot be undeclared", "Invalid access to undeclared parameter(s): []")."""
    names = [p.name for p in parameter_msgs]
    if any(name and name in reason for name in names):
        return reason
    undeclared = [p.name for p in parameter_msgs if not node.has_parameter(p.name)]
    unset = [p.name for p in parameter_msgs if p.value.type == 0]
    clash = []
    for p in parameter_msgs:
        if p.name in undeclared or p.value.type == 0:
            continue
        descriptor = node.describe_parameter(p.name)
        if not descriptor.dynamic_typing and p.value.type != descriptor.type:
            clash.append(p.name)
    culprits = (undeclared if 'undeclared parameter' in reason else
                unset if 'undeclared' in reason else
                clash if 'type' in reason else []) or names
    return f"{', '.join(culprits)}: {reason}"


def guard_services(node, log):
    """Wrap every service callback of ``node`` so that no request can raise into the executor.

    A callback that raises or returns something other than its response type answers a
    refusal naming the error instead, and ``log(message)`` is told. Parameter requests are
    answered per parameter as ROS 2 specifies them, and every refusal names its parameter:
    ``SetParameters`` (each parameter on its own) sets each readable parameter through the
    callback one at a time, so one that cannot be read (a type number that is no
    ``Parameter.Type``, such as 200) is refused alone, not with the ones before it that were
    already applied; ``SetParametersAtomically`` refuses the whole request, naming the
    parameter at fault.
    """
    for srv in node.services:
        if getattr(srv.callback, '_guarded', False):
            continue
        original, response_type, name = srv.callback, srv.srv_type.Response, srv.srv_name
        request_type = srv.srv_type.Request

        def call(cb, request, _type, _name):
            try:
                out = cb(request, _type())
                if isinstance(out, _type):
                    return out
                reason = f'internal error: the callback returned {type(out).__name__}'
            except Exception as exc:   # any request must get an answer, never stop the node
                reason = f'refused: {type(exc).__name__}: {exc}'
            log(f'service {_name}: {reason}')
            return _refusal(request, _type(), reason)

        def guarded(request, response, _cb=original, _type=response_type, _name=name,
                    _request=request_type):
            parameters = getattr(request, 'parameters', None)
            if parameters is None:
                return call(_cb, request, _type, _name)
            if hasattr(response, 'results'):   # SetParameters: one at a time
                results = []
                for prm in parameters:
                    problem = _unreadable(prm)
                    if problem:
                        results.append(_refusal(_request(parameters=[prm]), _type(),
                                                problem).results[0])
                        continue
                    out = call(_cb, _request(parameters=[prm]), _type, _name)
                    result = (out.results[0] if len(out.results) == 1 else _refusal(
                        _request(parameters=[prm]), _type(),
                        'internal error: no result').results[0])
                    if not result.successful:
                        result.reason = _naming(node, [prm], result.reason)
                    results.append(result)
                response.results = results
                return response
            problem = next(filter(None, map(_unreadable, parameters)), '')
            if problem:   # atomic: nothing is applied
                return _refusal(request, _type(), problem)
            out = call(_cb, request, _type, _name)
            if hasattr(out, 'result') and not out.result.successful:
                out.result.reason = _naming(node, parameters, out.result.reason)
            return out

        guarded._guarded = True
        srv.callback = guarded


__all__ = ['ImuPacker', 'Outlet', 'StampedPacker', 'guard_services', 'ignore_further_interrupts',
           'set_stamp', 'settle_interrupt', 'shutdown_quietly', 'spin_guarded', 'stamp',
           'type_name']


def spin_guarded(executor, report):
    """Spin ``executor`` until shutdown; a callback that raises is reported, not fatal.

    Any process on the domain can send a malformed message or request, so no exception from a
    callback may stop the node; Ctrl-C and an external shutdown still end the loop (raised to
    the caller).

    Parameters
    ----------
    executor : rclpy.executors.Executor
        With the node added.
    report : callable
        Called with the exception (e.g. a throttled error log).
    """
    from rclpy.executors import ExternalShutdownException
    while executor.context.ok():
        try:
            executor.spin_once(timeout_sec=0.5)
        except (KeyboardInterrupt, ExternalShutdownException):
            raise
        except Exception as exc:   # a malformed message or request must not stop the node
            if not executor.context.ok():
                # Ctrl-C shut the context down under the wait ("context is not valid")
                raise ExternalShutdownException() from exc
            report(exc)


def freeze_start_up_heap():
    """Collect once, then move every object alive after start-up out of the garbage
    collector's reach (``gc.freeze``), before a node's paced work begins.

    A node's start-up leaves some 136,000 container objects (rclpy, NumPy, Numba, the
    model) that live as long as the process. Python's collector walks all of them in each
    full collection, and a full collection holds the GIL for about 150 ms on this 2-core
    machine: the stepping thread stood still for it and a 1 s window fell to 0.90 x real
    time. Frozen, they are never walked again; objects made afterwards are collected as
    usual. Call it from a ``main`` (a process entry point), not from a node's constructor:
    tests build many nodes in one process.

    Returns
    -------
    int
        Objects frozen (the permanent generation's count, dimensionless).
    """
    import gc
    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()


def ignore_further_interrupts():
    """After the first Ctrl-C of a ``main``, ignore SIGINT while it cleans up.

    ``ros2 launch`` without a terminal signals the whole process group, so a node gets the
    launch's SIGINT and the group's: the second one interrupted ``destroy_node`` with a
    traceback (launch reported exit code -2); the first one already asked to stop.
    """
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def settle_interrupt(context=None, timeout_s=1.0):
    """After Ctrl-C, wait up to ``timeout_s`` (s) for rclpy's SIGINT handler to shut down.

    That handler shuts the context down on a thread of its own while the main thread gets
    ``KeyboardInterrupt``: tearing the nodes down, or calling ``try_shutdown``, at the same
    moment raced it (``rcl_shutdown already called``, 3 of 60 SIGINTs to ``replay`` with the
    cores loaded). Call this at the start of a ``main``'s clean-up when it was interrupted.
    """
    import rclpy
    context = context or rclpy.get_default_context()
    end = time.monotonic() + timeout_s
    while context.ok() and time.monotonic() < end:
        time.sleep(0.005)


def shutdown_quietly(context=None):
    """``rclpy.try_shutdown``, taking "already shut down" by the SIGINT handler as done."""
    import rclpy
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    try:
        rclpy.try_shutdown(context=context)
    except _rclpy.RCLError:
        if (context or rclpy.get_default_context()).ok():
            raise   # a failure of our own, not the handler's shutdown


class HandoffLock:
    """A re-entrant lock that the stepping thread hands over when someone waits for it.

    Python locks are not fair: a thread that releases a lock and takes it again at once
    keeps winning, and stepping flat out (``real_time_factor`` 0) would starve commands and
    diagnostics. Waiters are counted; :meth:`hand_over`, called by the stepper between
    chunks, pauses 0.5 ms when anyone waits.
    """

    def __init__(self):
        self._lock = threading.RLock()
        self.waiting = 0

    def __enter__(self):
        self.waiting += 1
        self._lock.acquire()
        self.waiting -= 1
        return self

    def __exit__(self, *exc_info):
        self._lock.release()

    def acquire(self, timeout):
        """Take the lock, waiting at most ``timeout`` s; True when taken (release it)."""
        self.waiting += 1
        try:
            return self._lock.acquire(timeout=timeout)
        finally:
            self.waiting -= 1

    def release(self):
        """Release a lock taken with :meth:`acquire`."""
        self._lock.release()

    def hand_over(self):
        """Let a waiting thread take the lock (call with the lock released)."""
        if self.waiting > 0:
            time.sleep(0.0005)


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
