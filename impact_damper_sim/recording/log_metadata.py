"""The metadata records of a node's log, as plain YAML-safe data (str to str).

:func:`run_metadata` opens a log (software, scene, parameters and the run's
:func:`run_labels`: what a detector is scored against); :func:`fault_metadata` closes it
(every sensor fault of the run and what it did). ``vibration_node`` and ``study record``
write the same records. The live simulation and scene are read by attribute (duck-typed):
nothing here imports rclpy or :mod:`..live`.
"""
from __future__ import annotations

import numpy as np


def run_labels(live, scene_model):
    """What a detector is scored against, as plain data: the run's labels at sim time now.

    Parameters
    ----------
    live : LiveSimulation
        The simulation (read: ``t``, ``noise_seed``, ``noise_std``, ``dampers_enabled``,
        ``unbalance``, ``profile``, ``accelerometers``, ``channels``).
    scene_model : SceneModel
        Its scene (``scene['structure']``: the cross-couplings).

    Returns
    -------
    dict
        ``sim_time_s`` (when these values hold: the log's start; a later change is in the
        log as the command or parameter change it was), ``seed`` (the noise seed, which
        seeds every random stage of the channels), ``noise_std`` (m/s^2),
        ``dampers_enabled``, ``unbalance_multiplier`` (X, None without unbalance),
        ``rotor_speed_rad_s`` (None without a rotor), ``kcc_n_per_m`` (the scene's
        cross-coupled stiffness, summed over its cross-couplings; 0 without) with
        ``cross_couplings`` (each: node, kcc N/m, dofs), ``accelerometers``: per
        accelerometer its node, frame and ``channel`` (the preset and every stage's values,
        :meth:`~impact_damper_sim.live.channel.SensorChannel.labels`), and ``faults``: the
        sensor faults added so far (``FaultInjector.labels``: kind, values, seed, window);
        those added later, and what every fault did, are in :func:`fault_metadata`, written
        when the log closes. Every value SI.
    """
    structure = scene_model.scene.get('structure') or {}
    couplings = [{'node': c['node'], 'kcc': c['kcc'], 'dofs': list(c['dofs'])}
                 for c in structure.get('cross_couplings') or ()]
    return plain({
        'sim_time_s': float(live.t),
        'seed': int(live.noise_seed),
        'noise_std': float(live.noise_std),
        'dampers_enabled': bool(live.dampers_enabled),
        'unbalance_multiplier': (None if live.unbalance is None
                                 else float(live.unbalance.multiplier)),
        'rotor_speed_rad_s': (None if live.profile is None
                              else float(live.profile.speed(np.asarray(live.t)))),
        'kcc_n_per_m': float(sum(c['kcc'] for c in couplings)),
        'cross_couplings': couplings,
        'accelerometers': {acc.name: {'node': acc.node, 'frame_id': acc.frame_id,
                                      'channel': channel.labels()}
                           for acc, channel in zip(live.accelerometers, live.channels)},
        'faults': live.faults.labels(),
    })


#: name of the metadata record with the run's sensor faults, written when a log closes
FAULTS_METADATA = 'impact_damper_sim_faults'


def fault_metadata(live):
    """The :data:`FAULTS_METADATA` record: every sensor fault of the run and what it did.

    Written when the log closes (``study record`` at its end, the node when recording
    stops): faults come on command after the log opened, so the opening ``labels`` cannot
    hold them. The node's ``/diagnostics`` never mention faults (a real sensor does not
    report its own); this record does.

    Parameters
    ----------
    live : LiveSimulation
        The simulation (read: ``t``, ``faults``).

    Returns
    -------
    dict of str to str
        ``sim_time_s`` (how far the run went) and ``faults``: YAML of
        ``FaultInjector.labels()``, one entry per fault in the order added: ``name``,
        ``kind``, ``accelerometer``, ``axes``, ``stage``, ``seed``, ``parameters`` (SI),
        ``requested`` onset and duration, the actual window ``onset_s`` < t <= ``end_s``
        (None: until the end of the run), ``cleared_at_s``, ``samples`` in the window,
        and ``events`` (spike times, open periods).
    """
    import yaml
    return {'sim_time_s': repr(float(live.t)),
            'faults': yaml.safe_dump(plain(live.faults.labels()), sort_keys=False)}


def run_metadata(scene_model, overrides, parameters, node_name, live=None):
    """The ``impact_damper_sim`` metadata record that opens the node's logs (str to str).

    Parameters
    ----------
    scene_model : SceneModel
        The scene run (``name``, ``source``, ``scene``: its resolved SI tree).
    overrides : sequence of str
        The ``key=value`` scene overrides.
    parameters : dict
        The node's parameters (or ``study record``'s equivalents), as YAML-safe values.
    node_name : str
        Fully qualified node name.
    live : LiveSimulation, optional
        The simulation about to be logged: its :func:`run_labels` are the ``labels`` entry.

    Returns
    -------
    dict of str to str
        Software version, scene, overrides, the resolved scene in SI, the parameters, the
        node name, the time base and (with ``live``) ``labels`` (YAML); nothing that changes
        from run to run.
    """
    import yaml

    import impact_damper_sim
    labels = {} if live is None else {
        'labels': yaml.safe_dump(run_labels(live, scene_model), sort_keys=False)}
    return {
        'software_version': impact_damper_sim.__version__,
        'scene': scene_model.name, 'scene_source': str(scene_model.source),
        'overrides': yaml.safe_dump(list(overrides or ()), default_flow_style=True).strip(),
        'resolved_scene_si': yaml.safe_dump(plain(scene_model.scene), sort_keys=False),
        'node_parameters': yaml.safe_dump(plain(dict(parameters)), sort_keys=True),
        'node_name': node_name,
        'time_base': 'sim time (log_time = publish_time = sim time of the publish call)',
        **labels,
    }


def plain(value):
    """A value as plain YAML-safe data (tuples to lists, NumPy to Python)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


__all__ = ['FAULTS_METADATA', 'fault_metadata', 'plain', 'run_labels', 'run_metadata']
