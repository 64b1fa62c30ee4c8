"""Child process of test_recording.py: record std_msgs/Float64 at a steady rate until stopped.

Usage: ``python record_child.py OUT.mcap TIMES.txt RATE_HZ``

Writes message ``i`` (``data = i``) to ``/counter`` through an :class:`AsyncRecorder` with
log and publish time = the wall time of the write (ns), and after each write appends the line
``i time_ns`` to TIMES.txt (unbuffered, so a SIGKILL loses no line of a written message).
Prints ``ready`` once recording. SIGINT raises KeyboardInterrupt and the main code closes the
recorder; SIGTERM closes it inside the signal handler itself (interrupting whatever the main
code was doing). Either way the file is finalized, the stats are printed as JSON and the exit
status is 0.
"""
import json
import os
import signal
import sys
import time

from rclpy.serialization import serialize_message
from std_msgs.msg import Float64

from impact_damper_sim.recording import AsyncRecorder

QOS = {'history': 'keep_last', 'depth': 10, 'reliability': 'reliable',
       'durability': 'volatile'}


def main(out, times_path, rate):
    # Ctrl-C raises KeyboardInterrupt even if this process was started with SIGINT ignored
    # (a child of a background job inherits that, and Python then installs no handler)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    recorder = AsyncRecorder(out)

    def on_sigterm(signum, frame):
        print(json.dumps(recorder.close()), flush=True)   # close() from the handler itself
        raise SystemExit(0)
    signal.signal(signal.SIGTERM, on_sigterm)
    recorder.add_metadata('impact_damper_sim', {'scene': 'child: true\n', 'version': 'test'})
    recorder.add_topic('/counter', 'std_msgs/msg/Float64', QOS)
    times = os.open(times_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND, 0o644)
    period_ns = int(1e9 / rate)
    print('ready', flush=True)
    try:
        next_ns = time.time_ns()
        i = 0
        while True:
            now = time.time_ns()
            recorder.write('/counter', 'std_msgs/msg/Float64', QOS,
                           serialize_message(Float64(data=float(i))), now, now)
            os.write(times, f'{i} {now}\n'.encode())
            i += 1
            next_ns += period_ns
            time.sleep(max(0.0, (next_ns - time.time_ns()) / 1e9))
    except KeyboardInterrupt:
        stats = recorder.close()
        print(json.dumps(stats), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1], sys.argv[2], float(sys.argv[3])))
