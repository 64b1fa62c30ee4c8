#!/usr/bin/env bash
# Install the ROS 2 Jazzy command line (ros2 run, launch, topic, param, node, service, pkg,
# interface) and launch (launch, launch_xml, launch_yaml, launch_ros) into a venv built from
# the PyPI ROS 2 wheels (requirements.txt). PyPI does not carry them. `make ros2cli` runs this.
#
# Usage: tools/install_ros2cli.sh VENV [pip args for the PyPI part, e.g. -c constraints.txt]
#
# Source, in this order:
# 1. $ROS2CLI_WHEELS (default ../shared/ros2cli beside the checkout), when it holds install.sh:
#    pure-Python wheels built from the jazzy branches, installed offline (its README).
# 2. Otherwise the jazzy branches of ros2/ros2cli, ros2/launch, ros2/launch_ros and
#    ros2/rosidl_runtime_py, with pip's git URLs (needs git and the network), then the one
#    change the wheels carry: launch_ros imports composition_interfaces, which has no PyPI
#    wheel; the import is made optional (only LoadComposableNodes/ComposableNodeContainer
#    need it).
# Then: export AMENT_PREFIX_PATH=VENV; VENV/bin/ros2 --help
set -euo pipefail
venv="${1:?usage: tools/install_ros2cli.sh VENV [pip args]}"; shift
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
wheels="${ROS2CLI_WHEELS:-$here/../shared/ros2cli}"
[ -x "$venv/bin/python" ] || { echo "install_ros2cli: no venv at $venv (run make first)" >&2; exit 2; }

if [ -f "$wheels/install.sh" ]; then
    echo "install_ros2cli: from $wheels"
    bash "$wheels/install.sh" "$venv" --quiet "$@"
    exit 0
fi

echo "install_ros2cli: $wheels/install.sh not found; from the jazzy branches upstream (git)"
pip=("$venv/bin/python" -m pip)
# What the source packages import, from PyPI by name (as ../shared/ros2cli/install.sh). Not
# `lark`: lark-parser (from the rosidl wheels) provides the same module and launch works with it.
"${pip[@]}" install --quiet "$@" \
    'ros-jazzy-rclpy[fastrtps]' ros-jazzy-rcl-interfaces ros-jazzy-lifecycle-msgs \
    ros-jazzy-ament-index-python ros-jazzy-rosidl-parser ros-jazzy-rosidl-adapter \
    osrf-pycommon argcomplete psutil pyyaml packaging importlib-metadata numpy
# --no-deps: launch_ros declares `ament_index_python`, a name no PyPI distribution has
gh=https://github.com/ros2
"${pip[@]}" install --quiet --no-deps \
    "rosidl_runtime_py @ git+$gh/rosidl_runtime_py.git@jazzy" \
    "launch @ git+$gh/launch.git@jazzy#subdirectory=launch" \
    "launch_xml @ git+$gh/launch.git@jazzy#subdirectory=launch_xml" \
    "launch_yaml @ git+$gh/launch.git@jazzy#subdirectory=launch_yaml" \
    "launch_ros @ git+$gh/launch_ros.git@jazzy#subdirectory=launch_ros" \
    "ros2launch @ git+$gh/launch_ros.git@jazzy#subdirectory=ros2launch" \
    "ros2cli @ git+$gh/ros2cli.git@jazzy#subdirectory=ros2cli" \
    "ros2run @ git+$gh/ros2cli.git@jazzy#subdirectory=ros2run" \
    "ros2topic @ git+$gh/ros2cli.git@jazzy#subdirectory=ros2topic" \
    "ros2param @ git+$gh/ros2cli.git@jazzy#subdirectory=ros2param" \
    "ros2node @ git+$gh/ros2cli.git@jazzy#subdirectory=ros2node" \
    "ros2service @ git+$gh/ros2cli.git@jazzy#subdirectory=ros2service" \
    "ros2pkg @ git+$gh/ros2cli.git@jazzy#subdirectory=ros2pkg" \
    "ros2interface @ git+$gh/ros2cli.git@jazzy#subdirectory=ros2interface"
"$venv/bin/python" - <<'EOF'
"""Make launch_ros's composition_interfaces import optional (it has no PyPI wheel)."""
import importlib.util
import pathlib

spec = importlib.util.find_spec('launch_ros')
path = pathlib.Path(spec.origin).parent / 'actions' / 'load_composable_nodes.py'
text = path.read_text()
old = 'import composition_interfaces.srv\n'
new = ('try:\n    import composition_interfaces.srv\n'
       'except ImportError:  # not installed (PyPI ROS wheels): LoadComposableNodes unusable\n'
       '    composition_interfaces = None\n')
if new not in text:
    if old not in text:
        raise SystemExit(f'install_ros2cli: {path} has no line {old.strip()!r} to make optional')
    if 'from __future__ import annotations' not in text:   # its annotations name the module
        text = text.replace('\nfrom pathlib import Path', '\nfrom __future__ import annotations'
                            '\n\nfrom pathlib import Path', 1)
    path.write_text(text.replace(old, new, 1))
EOF
echo "install_ros2cli: installed; set AMENT_PREFIX_PATH=$venv before using ros2"
