"""Start vibration_node on a scene it must refuse; its one line (tests of the budgets)."""
import os
import subprocess
import sys


def node_refusal(scene_path, timeout=120):
    """Run the node on ``scene_path`` and return its ``vibration_node:`` lines on stderr,
    after checking it exited with status 2 (a refusal, not a crash)."""
    proc = subprocess.run(
        [sys.executable, '-m', 'impact_damper_sim.ros.vibration_node', '--ros-args',
         '-p', f'scene:={scene_path}'], capture_output=True, text=True, timeout=timeout,
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST'))
    assert proc.returncode == 2, proc.stderr
    return [x for x in proc.stderr.splitlines() if x.startswith('vibration_node:')], proc.stderr
