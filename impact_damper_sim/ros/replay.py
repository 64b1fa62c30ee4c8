"""``replay``: publish a recorded MCAP log with its original timing.

::

    replay FILE.mcap [--rate X] [--start-offset S] [--loop] [--topics T [T ...]]
                     [--remap OLD:=NEW [OLD:=NEW ...]] [--no-clock] [--clock-hz HZ]
                     [--delay S] [--ros-args ...]

Works on any MCAP with profile ``ros2`` whose message types are installed: logs written by
``vibration_node``'s recorder and by ``ros2 bag record``. Each message is published as the
raw CDR bytes it was recorded with (``Publisher.publish`` takes ``bytes`` in rclpy 7), so
replay costs no decoding. Messages go out in log_time order, each at

    wall deadline = (log_time - (log start + start offset)) / rate

after playback starts; a message that is late is published at once (never dropped). On
stdout, replay prints what it plays before the first message (the file, each topic with its
type and message count, the log time it spans, the rate) and a line at the end (messages
played, passes, wall time, the achieved lateness). ``/clock`` (``rosgraph_msgs/Clock``,
reliable, keep last 1) carries the log time every ``1/--clock-hz`` s of wall time; a tick that
is already late is skipped rather than sent in a burst. With ``--loop`` the log plays again
and again; a pass starts one mean inter-message interval (of log time) after the previous one
ended, and ``/clock`` jumps back to the log's start.

Each topic's publisher gets the QoS the recording publishers offered, read from the channel's
``offered_qos_profiles`` metadata (or, failing that, from the ``rosbag2`` metadata record):
reliability, durability, deadline, lifespan and liveliness as recorded; the recorded history
and depth when they are known, else keep last 10 (rosbag2 records offers from DDS discovery,
which carries no history). Unlike ``ros2 bag play`` a recorded keep-last depth is kept, so a
latched depth-1 topic gives a late joiner only the latest state, as the original did. A topic
without readable QoS, or whose publishers offered differing QoS, falls back to reliable,
volatile, keep last 10, with a warning. Policies are accepted as strings (bag metadata
version 9, Jazzy) or integers (older versions).

A file that is missing, empty, not MCAP, truncated, corrupt or not ROS 2, an unknown message
type or bad options give a one-line error on stderr and exit status 2.

The pacing (:class:`~impact_damper_sim.live.playback.Schedule`,
:class:`~impact_damper_sim.live.playback.Player`) knows nothing of ROS; the log is opened,
checked and planned (topics, types, QoS, remaps) by :func:`.replay_plan.prepare` before ROS
starts; this module holds :class:`ReplayNode`, which feeds the plan to the player and
publishes, and the command line.
"""
from __future__ import annotations

import argparse
import math
import sys
import threading
import time

import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from ..live.playback import Player
from ..studies.log_reader import LogError
from .interface import CLOCK, CLOCK_QOS
from .process import (
    freeze_start_up_heap,
    ignore_further_interrupts,
    settle_interrupt,
    shutdown_quietly,
)
from .replay_plan import describe, finished_line, prepare

EXIT_USAGE = 2
DEFAULT_CLOCK_HZ = 100.0


# --- node -------------------------------------------------------------------------------------

class ReplayNode(Node):
    """Publishes a planned log: one publisher per recorded topic, plus ``/clock``.

    Parameters
    ----------
    plan : Plan
        From :func:`prepare`.
    clock : bool
        Publish ``/clock`` from the log time.
    clock_hz : float
        Clock ticks per second of wall time (Hz).
    node_name : str
        Node name.
    **kwargs
        Passed to ``rclpy.node.Node`` (e.g. ``context``, ``namespace``).
    """

    def __init__(self, plan, *, clock=True, clock_hz=DEFAULT_CLOCK_HZ, node_name='replay',
                 **kwargs):
        if not (math.isfinite(clock_hz) and clock_hz > 0):
            raise ValueError(f'--clock-hz must be > 0, got {clock_hz}')
        super().__init__(node_name, **kwargs)
        self.plan = plan
        self._clock_period = 1.0 / clock_hz
        self._stop = threading.Event()
        self.context.on_shutdown(self._stop.set)
        self._publishers_by_channel = {}
        for w in plan.warnings:
            self.get_logger().warning(w)
        for tr in plan.tracks:
            for w in tr.warnings:
                self.get_logger().warning(w)
            self._publishers_by_channel[tr.channel_id] = self.create_publisher(
                tr.msg_class, tr.out_topic, tr.qos)
        self._clock_pub = None
        if clock:
            from rosgraph_msgs.msg import Clock
            self._clock_msg = Clock()
            self._clock_pub = self.create_publisher(Clock, CLOCK, CLOCK_QOS)
        self._topics = sorted({tr.topic for tr in plan.tracks})
        self.stats = None

    def play(self):
        """Play the log in the calling thread (blocks; :meth:`stop` ends it early).

        Returns
        -------
        PlaybackStats
        """
        player = Player(self.plan.schedule, self._source, self._publish,
                        clock=self._publish_clock if self._clock_pub is not None else None,
                        clock_period=self._clock_period, stop=self._stop)
        self.stats = player.run()
        return self.stats

    def stop(self):
        """End :meth:`play` early (thread-safe)."""
        self._stop.set()

    def wait_for_acks(self, timeout_s=1.0):
        """Wait up to ``timeout_s`` (s) for reliable subscribers to acknowledge everything."""
        deadline = time.monotonic() + timeout_s
        for pub in self._publishers_by_channel.values():
            left = max(0.0, deadline - time.monotonic())
            pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))

    def _source(self):
        for ch, msg in self.plan.log.messages(topics=self._topics):
            if ch.id in self._publishers_by_channel:
                data = msg.data
                yield ch.id, msg.log_time, data if isinstance(data, bytes) else bytes(data)

    def _publish(self, channel_id, data):
        self._publishers_by_channel[channel_id].publish(data)   # raw CDR: no decoding

    def _publish_clock(self, log_time_ns):
        sec, nanosec = divmod(int(log_time_ns), 1_000_000_000)
        self._clock_msg.clock.sec, self._clock_msg.clock.nanosec = sec, nanosec
        self._clock_pub.publish(self._clock_msg)


# --- command line -----------------------------------------------------------------------------

def _parser():
    p = argparse.ArgumentParser(
        prog='replay',
        description='Publish a recorded MCAP log (rosbag2 layout, profile ros2) with its '
                    'original timing, its recorded QoS and /clock from the log time.')
    p.add_argument('file', metavar='FILE', help='the .mcap file')
    p.add_argument('--rate', type=float, default=1.0,
                   help='playback speed factor (> 0, default 1; 2 is twice as fast)')
    p.add_argument('--start-offset', type=float, default=0.0, metavar='S',
                   help='skip this much log time at the start (s, default 0)')
    p.add_argument('--loop', action='store_true', help='play again and again')
    p.add_argument('--topics', nargs='+', action='extend', default=[], metavar='TOPIC',
                   help='replay only these topics (repeatable; default all)')
    p.add_argument('--remap', nargs='+', action='extend', default=[], metavar='OLD:=NEW',
                   help='publish topic OLD as NEW (repeatable)')
    p.add_argument('--no-clock', action='store_true', help='do not publish /clock')
    p.add_argument('--clock-hz', type=float, default=DEFAULT_CLOCK_HZ, metavar='HZ',
                   help=f'/clock ticks per wall second (Hz, default {DEFAULT_CLOCK_HZ:g})')
    p.add_argument('--delay', type=float, default=0.0, metavar='S',
                   help='wait this long before playing, e.g. for discovery (s, default 0)')
    return p


def _split_ros_args(argv):
    """Split ``argv`` into ours and the ``--ros-args ... [--]`` blocks.

    rcl would also take a bare ``OLD:=NEW`` outside ``--ros-args`` as a (deprecated) global
    remap rule, so the values of ``--remap`` must never reach it.
    """
    ours, ros_args, inside = [], [], False
    for arg in argv:
        if arg == '--ros-args':
            inside = True
            ros_args.append(arg)
        elif inside and arg == '--':
            inside = False
            ros_args.append(arg)
        else:
            (ros_args if inside else ours).append(arg)
    return ours, ros_args


def _error(message):
    print(f"replay: error: {' '.join(str(message).split())}", file=sys.stderr)


def main(args=None):
    """Run the ``replay`` executable.

    Parameters
    ----------
    args : list of str, optional
        Command-line arguments without the program name (ROS arguments after
        ``--ros-args`` included); default ``sys.argv[1:]``.

    Returns
    -------
    int
        Exit status: 0 when played (or interrupted), 2 for bad input or a bad file.
    """
    argv = list(sys.argv[1:] if args is None else args)
    ours, ros_args = _split_ros_args(argv)
    try:
        options = _parser().parse_args(ours)
    except SystemExit as exc:   # argparse printed the usage and the problem
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    try:
        if not (math.isfinite(options.delay) and options.delay >= 0):
            raise ValueError(f'--delay must be >= 0 s, got {options.delay}')
        if not (math.isfinite(options.clock_hz) and options.clock_hz > 0):
            raise ValueError(f'--clock-hz must be > 0, got {options.clock_hz}')
        # check the file and the types before bringing up ROS
        plan = prepare(options.file, options.topics, options.remap, options.rate,
                       options.start_offset, options.loop)
    except (LogError, ValueError) as exc:
        _error(exc)
        return EXIT_USAGE
    rclpy.init(args=['replay'] + ros_args)
    node = executor = spinner = None
    status = 0
    try:
        node = ReplayNode(plan, clock=not options.no_clock, clock_hz=options.clock_hz)
        freeze_start_up_heap()   # paced playing: no full collections of start-up objects
        # spin in the background (graph and parameter services); play in this thread
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        spinner = threading.Thread(target=_spin_quietly, args=(executor,), daemon=True)
        spinner.start()
        # on stdout: what plays, before the first message, and what played at the end
        print('\n'.join(describe(plan)), flush=True)
        if options.delay and node._stop.wait(options.delay):
            raise ExternalShutdownException()
        stats = node.play()
        if stats.stopped and not rclpy.ok():
            raise ExternalShutdownException()
        node.wait_for_acks(1.0)
        print(finished_line(stats), flush=True)
    except (KeyboardInterrupt, ExternalShutdownException):
        ignore_further_interrupts()
        settle_interrupt()
    except LogError as exc:   # damage found while reading on
        _error(exc)
        status = EXIT_USAGE
    finally:
        if node is not None:
            node.stop()
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        shutdown_quietly()
        if spinner is not None:
            spinner.join(timeout=1.0)
    return status


def _spin_quietly(executor):
    """Spin until shutdown; Ctrl-C shuts the context down under the spin, which is no error
    (nor is the wait set rclpy was making at that moment: "the given context is not valid")."""
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if executor.context.ok():
            raise


if __name__ == '__main__':
    sys.exit(main())
