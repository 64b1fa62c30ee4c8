"""The node's packer writes its messages from templates made once and whole NumPy blocks; these
tests hold it to the bytes of the plain way: rows field by field through
``BatchEncoder.encode``, ``CdrWriter`` for the rotor messages, ``joint_state_cdr``. Equal
simulations must give equal bytes on the node and in ``study record`` logs, so the two may
not differ in a single byte: over chunks with impacts (plane and one-directional impactors),
keyphasor turns, two accelerometers, the ground truth and a dropout fault (rows and Imu
samples missing on one accelerometer only)."""
import math

import numpy as np
import pytest

from impact_damper_sim.integrate.events import IMPACT
from impact_damper_sim.live.realtime import LiveSimulation
from impact_damper_sim.live.streams import live_scene
from impact_damper_sim.recording import message_cdr as mc
from impact_damper_sim.recording.batches import (
    ACCEL_FIELDS,
    ACCEL_POINT_STEP,
    IMPACT_FIELDS,
    IMPACT_POINT_STEP,
    KEYPHASOR_FIELDS,
    KEYPHASOR_POINT_STEP,
    TACH_FIELDS,
    TACH_POINT_STEP,
    BatchEncoder,
    CdrWriter,
)
from impact_damper_sim.recording.node_messages import NodeMessages, rotor_frame_id

LAYOUTS = [(ACCEL_FIELDS, ACCEL_POINT_STEP), (IMPACT_FIELDS, IMPACT_POINT_STEP),
           (TACH_FIELDS, TACH_POINT_STEP), (KEYPHASOR_FIELDS, KEYPHASOR_POINT_STEP)]


def _reference_batch(messages, batch):
    """``batch_items`` written the plain way: structured rows per accelerometer, encoded
    field by field (the packer before it was made from templates)."""
    live, scene = messages.live, messages.scene
    accs = live.accelerometers
    delay_ns = int(round(live.imu_delay * 1e9))
    imu_ns = np.rint(batch.imu_t * 1e9).astype(np.int64)
    items = []
    for a, (acc, var) in enumerate(zip(accs, live.imu_noise_variances())):
        keep = np.ones(imu_ns.size, bool) if batch.imu_valid is None else batch.imu_valid[:, a]
        data = mc.ImuEncoder(acc.frame_id, var).pack(
            imu_ns[keep], batch.imu_linear_acceleration[keep, a, :],
            batch.imu_angular_velocity[keep, a, :])
        items += [(ns + delay_ns, a, messages.imu[a], d)
                  for ns, d in zip(imu_ns[keep].tolist(), data)]
    t_ns = np.rint(batch.t * 1e9).astype(np.int64)
    if t_ns.size:
        for a, acc in enumerate(accs):
            encoder = BatchEncoder(acc.frame_id, ACCEL_FIELDS, ACCEL_POINT_STEP)
            rows = np.empty(t_ns.size, encoder.dtype)
            rows['t'] = (t_ns - t_ns[0]) * 1e-9
            for j, name in enumerate(('ax', 'ay', 'az')):
                rows[name] = batch.linear_acceleration[:, a, j]
                rows['w' + name[1]] = batch.angular_velocity[:, a, j]
            keep = np.ones(t_ns.size, bool) if batch.valid is None else batch.valid[:, a]
            items.append((int(t_ns[-1]), a, messages.batch[a],
                          encoder.encode(t_ns[0], rows[keep])))
            if messages.truth:
                for j, name in enumerate(('ax', 'ay', 'az')):
                    rows[name] = batch.truth[:, a, j]
                items.append((int(t_ns[-1]), a, messages.truth[a],
                              encoder.encode(t_ns[0], rows)))
    end_ns = int(round(live.t * 1e9))
    start = messages.impacts_from
    if scene.impactors:
        ev = batch.events[batch.events['kind'] == IMPACT]
        encoder = BatchEncoder(messages.impactor_frame, IMPACT_FIELDS, IMPACT_POINT_STEP)
        rows = np.zeros(ev.size, encoder.dtype)
        ns = np.rint(ev['t'] * 1e9).astype(np.int64)
        rows['t'] = (ns - start) * 1e-9
        rows['impactor'] = ev['impactor']
        for i, e in enumerate(ev):
            for k, axis in enumerate(messages.impactor_axes[e['impactor']]):
                rows[('jx', 'jy', 'jz')[axis]][i] = e['impulse'] * e['normal'][k]
        rows['v_approach'] = np.abs(ev['v_n'])
        rows['v_separation'] = np.abs(ev['v_n_after'])
        rows['energy'] = ev['loss']
        items.append((end_ns, len(accs), messages.impacts,
                      encoder.encode(start, rows[np.argsort(ns, kind='stable')])))
    if messages.tach is not None:
        frame = rotor_frame_id(scene.name)
        if t_ns.size:
            encoder = BatchEncoder(frame, TACH_FIELDS, TACH_POINT_STEP)
            rows = np.empty(t_ns.size, encoder.dtype)
            rows['t'] = (t_ns - t_ns[0]) * 1e-9
            rows['angle'], rows['speed'] = batch.shaft_angle, batch.shaft_speed
            items.append((end_ns, len(accs), messages.tach, encoder.encode(t_ns[0], rows)))
        encoder = BatchEncoder(frame, KEYPHASOR_FIELDS, KEYPHASOR_POINT_STEP)
        events = batch.keyphasor
        rows = np.empty(events.size, encoder.dtype)
        rows['t'] = np.maximum(events['t'] - start * 1e-9, 0.0)
        rows['revolution'], rows['speed'] = events['revolution'], events['speed']
        items.append((end_ns, len(accs), messages.keyphasor, encoder.encode(start, rows)))
    items.sort(key=lambda item: item[:2])
    return [(ns, stream, data) for ns, _, stream, data in items]


def _reference_time(messages):
    """``time_items`` written field by field with ``CdrWriter`` and ``joint_state_cdr``."""
    live = messages.live
    ns = int(round(live.t * 1e9))
    items = [(ns, messages.clock, mc.clock_cdr(ns))]
    if live.has_rotor:
        speed, rate, x = live.rotor_state()
        w = CdrWriter()
        w.stamp(ns)
        w.string(messages.rotor_frame)
        w.put('3d', speed, rate, x)
        items.append((ns, messages.speed, w.bytes()))
        angle = float(live.profile.angle(np.asarray(live.t))) % (2.0 * math.pi)
        items.append((ns, messages.joint, mc.joint_state_cdr(
            ns, ['rotor'], [angle], [speed], frame_id=messages.rotor_frame)))
    return items


# rbs_kcc with a second accelerometer: plane impactors hit from the first chunk, a rotor;
# sdof: a one-directional impactor (its second normal component has no axis)
TWO_ACCELEROMETERS = ('sensors=[{name: a, node: 4, dof: uy}, {name: b, node: 4, dof: uz}, '
                      '{name: c, node: 14, dof: uy}]',)


@pytest.mark.parametrize('scene_name, overrides, chunks', [
    ('rbs_kcc', TWO_ACCELEROMETERS, 60), ('sdof', (), 60)])
def test_the_packer_writes_the_plain_ways_bytes(scene_name, overrides, chunks):
    model, target = live_scene(scene_name, overrides)
    live = LiveSimulation(model, initial_target=target, noise_std=0.2, seed=4)
    messages = NodeMessages(live, model, truth=True)
    live.step(0)
    if len(live.accelerometers) > 1:   # rows and Imu samples lost on one accelerometer
        live.add_fault({'kind': 'dropout', 'accelerometer': live.accelerometers[1].name,
                        'onset': 0.2, 'duration': 0.1})
    seen = {'impacts': 0, 'keyphasor': 0, 'partial': 0}
    for i in range(chunks):
        if i == 25 and live.has_rotor:
            live.command_unbalance(3.0)
        batch = live.step(int(round(0.01 * live.sample_rate)))
        seen['impacts'] += int(np.count_nonzero(batch.events['kind'] == IMPACT))
        seen['keyphasor'] += 0 if batch.keyphasor is None else batch.keyphasor.size
        seen['partial'] += int(batch.valid is not None and not batch.valid.all())
        expected = _reference_batch(messages, batch)
        assert messages.batch_items(batch) == expected, f'chunk {i}'
        assert messages.time_items() == _reference_time(messages), f'chunk {i}'
    # the cases the comparison is for did occur
    assert seen['impacts'] > 0
    if live.has_rotor:
        assert seen['keyphasor'] > 0 and seen['partial'] > 0


@pytest.mark.parametrize('fields, step', LAYOUTS)
@pytest.mark.parametrize('frame', ['', 'a', 'abc', 'hpotp_casing_bottom'])
@pytest.mark.parametrize('n', [0, 1, 7])
def test_encode_data_is_encode_of_the_same_rows(fields, step, frame, n):
    rng = np.random.default_rng(n)
    encoder = BatchEncoder(frame, fields, step)
    rows = np.zeros(n, encoder.dtype)
    for name in rows.dtype.names:
        rows[name] = rng.integers(0, 9, n) if name in ('impactor', 'revolution') else \
            rng.normal(size=n)
    for stamp in (0, 12_345_678_901, 2**31 * 1_000_000_000 - 1):
        assert encoder.encode_data(stamp, n, rows.tobytes()) == encoder.encode(stamp, rows)


@pytest.mark.parametrize('frame', ['', 'f', 'abcd', 'hpotp_rotor', 'housing_é'])
def test_vector3_stamped_encoder_is_the_field_by_field_message(frame):
    for ns, vector in [(0, (0.0, 0.0, 0.0)), (10_000_000, (2400.0, -37.5, 2.5)),
                       (2**31 * 1_000_000_000 - 1, (math.inf, -0.0, math.nan))]:
        w = CdrWriter()
        w.stamp(ns)
        w.string(frame)
        w.put('3d', *vector)
        assert mc.Vector3StampedEncoder(frame).pack(ns, *vector) == w.bytes()
        assert mc.vector3_stamped_cdr(ns, frame, vector) == w.bytes()


@pytest.mark.parametrize('names', [[], ['rotor'], ['a/uy', 'a/uz', 'long_name/x']])
@pytest.mark.parametrize('frame', ['', 'hpotp_rotor', 'housing_é'])
def test_joint_state_encoder_without_effort_is_joint_state_cdr(names, frame):
    rng = np.random.default_rng(3)
    pos, vel = rng.normal(size=(2, len(names)))
    encoder = mc.JointStateEncoder(names, frame, effort=False)
    for ns in (0, 7_000_000_005, 2**31 * 1_000_000_000 - 1):
        expected = mc.joint_state_cdr(ns, names, pos, vel, frame_id=frame)
        assert encoder.pack(ns, pos, vel) == expected
        assert encoder.pack(ns, list(pos), tuple(vel)) == expected   # any sequence
