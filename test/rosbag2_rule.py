"""Test-side copy of rosbag2's schema rule (rosbag2_storage_mcap, jazzy), for fixture logs.

Written from rosbag2's ``local_message_definition_source.cpp``, independently of
``impact_damper_sim.recording``: the root ``.msg`` text, then each dependency not written
yet, depth first and sorted within each level, each as a newline, 80 ``=``, a newline,
``MSG: pkg/Type``, a newline and its text.
"""
import os
import re

import pytest

_FIELD = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_PRIMITIVES = {'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16',
               'uint16', 'int32', 'uint32', 'int64', 'uint64', 'string'}


def msg_text(name):
    """The installed ``.msg`` text of ``pkg/Type`` or ``pkg/msg/Type`` (skip if absent)."""
    ament = pytest.importorskip('ament_index_python.packages')
    pkg, typ = name.split('/')[0], name.split('/')[-1]
    try:
        share = ament.get_package_share_directory(pkg)
    except Exception:
        pytest.skip(f'{pkg} .msg files not installed (AMENT_PREFIX_PATH?)')
    with open(os.path.join(share, 'msg', typ + '.msg')) as fh:
        return fh.read()


def msgdef(rtype):
    """rosbag2_storage_mcap's concatenation: root, then unseen dependencies depth first."""
    seen = set()

    def rec(name):
        text = msg_text(name)
        pkg = name.split('/')[0]
        deps = {t if '/' in t else f'{pkg}/{t}' for t in _FIELD.findall(text)
                if t not in _PRIMITIVES}
        out = text
        for dep in sorted(deps):
            if dep not in seen:
                seen.add(dep)
                out += '\n' + '=' * 80 + '\nMSG: ' + dep + '\n' + rec(dep)
        return out
    return rec(rtype)
