"""The reliability probe of issue 29, kept as a fuzz test (item 5): a hostile peer and a careless
user, with fixed seeds and a bounded run time, so that what it found stays fixed.

* parameters of every type: every declared parameter x every ROS parameter type (and invalid
  type numbers), alone and in batches, through the node's own ``set_parameters`` and
  ``set_parameters_atomically`` service handlers (what a request off the wire reaches, minus
  DDS) and through ``Node.set_parameters``; the node is stepped after every request;
* command floods: random and hostile values on every topic the node subscribes to, by direct
  callback calls and over the wire;
* type clashes: a peer node (in a second rclpy context: one DDS participant refuses a
  clashing endpoint) publishes and subscribes with wrong types on every topic name of the node;
* bad files: mutated scene files through the scene loader, ``study simulate`` and the node's
  console entry point; corrupted copies of a small live recording through ``RosLog``,
  ``study report``, replay's ``prepare`` and ``study recover``;
* record toggles: many quick start/stop cycles with automatic names, over two runs.

Every case draws from ``random.Random`` seeded with :data:`SEED`, the test's name and its
scale, so a failure message (which names the case index and what was sent) reproduces. The
default selection runs each probe at scale 1: 30-40 s wall (14 s CPU) for the module on the
2-core machine at load average 7-9; it must stay under 60 s on a busy machine. ``-m slow``
runs the ``long`` variants at 10 times the counts (3.5 to 6.5 minutes, most of it loading
scenes with 5,000-item lists), and ``FUZZ_SCALE=N`` multiplies every count by N.

Defects found by the probe keep a minimal reproduction each at the end of the module (a
known one is pinned there by an ``xfail(strict=True)`` case, and the fuzz loops tolerate
exactly its signature, until it is fixed); the fuzz loops tolerate none now.
"""
import contextlib
import hashlib
import json
import math
import os
import random
import threading
import time
from collections import Counter

import numpy as np
import pytest

import fuzz_support as fz
from node_helpers import FakeClock, make_node

rclpy = pytest.importorskip('rclpy')

from rcl_interfaces.msg import Parameter as ParameterMsg  # noqa: E402
from rcl_interfaces.msg import ParameterType  # noqa: E402
from rcl_interfaces.srv import GetParameters, SetParameters, SetParametersAtomically  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402
from std_srvs.srv import SetBool  # noqa: E402

from impact_damper_sim.cli.study import main as study_main  # noqa: E402
from impact_damper_sim.ros import interface as itf  # noqa: E402
from impact_damper_sim.ros import node_recording, vibration_node  # noqa: E402
from impact_damper_sim.ros.parameters import PARAMETERS, check  # noqa: E402
from impact_damper_sim.ros.vibration_node import VibrationNode  # noqa: E402
from impact_damper_sim.scene.schema import SceneError  # noqa: E402

pytestmark = pytest.mark.ros
os.environ.setdefault('AMENT_PREFIX_PATH', __import__('sys').prefix)   # .msg files for MCAP

SEED = 29   # issue 29
#: multiplies every case count (the ``long`` variants multiply by 10 more)
ENV_SCALE = max(1, int(os.environ.get('FUZZ_SCALE', '1')))
LINEAR_HPOTP = ['impactors=[]']   # the HPOTP casing without impactors: a rotor, quick to step


@pytest.fixture(params=[pytest.param(1, id='quick'),
                        pytest.param(10, id='long', marks=pytest.mark.slow)])
def scale(request):
    """Case-count multiplier: 1 in the default selection, 10 under ``-m slow``."""
    return request.param * ENV_SCALE


def _rng(name, scale):
    return random.Random(f'{SEED}/{name}/{scale}')


def _service(node, name):
    """The (guarded) callback of the node's service ``name``: what a request off the wire
    reaches after DDS and deserialization."""
    matches = [s for s in node.services if s.srv_name.rsplit('/', 1)[-1] == name]
    assert len(matches) == 1, [s.srv_name for s in node.services]
    return matches[0].callback


def _one_line(text):
    return bool(text.strip()) and '\n' not in text.strip() and 'Traceback' not in text


class Stepper:
    """Steps a tick-driven node and checks what each step produces.

    Every stepped chunk goes through a spy on ``_queue_batch``: its sample times must be
    finite and increasing and its accelerations finite.
    """

    def __init__(self, node):
        self.node = node
        self.period = 1.0 / node.live.sample_rate
        self.bad = []
        self.samples = 0
        original = node.publishing.queue_batch

        def spy(batch, *args):
            t, acc = np.asarray(batch.t), np.asarray(batch.linear_acceleration)
            if not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)
                    and np.all(np.isfinite(acc))):
                self.bad.append((float(node.live.t), t.size))
            self.samples += t.size
            return original(batch, *args)

        node.publishing.queue_batch = spy

    def advance(self, where):
        """Advance the fake wall clock so that at most 20 ms of sim time is due, tick, and
        check that sim time moved as the current ``real_time_factor`` says (to one sample
        period); with factor 0 one chunk is stepped."""
        node = self.node
        rtf = node.pacer.real_time_factor
        t0 = node.live.t
        if rtf == 0:
            expected = node._chunk * self.period
        else:
            wall = min(0.03, 0.02 / rtf)
            node._wall.now += wall
            expected = rtf * wall
        node.tick()
        moved = node.live.t - t0
        assert node.live.failure is None, (where, node.live.failure)
        assert math.isfinite(node.live.t), where
        assert abs(moved - expected) <= self.period + 1e-9, (
            f'{where}: real_time_factor {rtf!r}: sim time moved {moved!r} s, expected '
            f'{expected!r} s to one sample period ({self.period} s)')
        assert not self.bad, f'{where}: non-finite or unordered samples in chunks {self.bad}'
        return moved

    def diagnostics_ok(self, where):
        """/diagnostics is OK or WARN (never ERROR: the simulation has not failed), one line."""
        self.node.publish_diagnostics()
        d = self.node.last_diagnostics
        assert d['level'] in (0, 1), (where, d['level'], d['message'])
        assert _one_line(d['message']), (where, d['message'])
        return d


# --------------------------------------------------------------------------- parameters

# no refusal reaches a service client without naming its parameter: rclpy's own (a wrong
# type, NOT_SET, an undeclared name it lists as ``[]``) are prefixed by the service guard
# (test_known_refusals_name_the_parameter); only a parameter whose name is empty is exempt


def _names_it(name, reason):
    return bool(name) and (name in reason or repr(name) in reason)


def _state_matches_parameters(node, where):
    """The node's live state agrees with its dynamic parameters."""
    p = {n: node.get_parameter(n).value for n in ('real_time_factor', 'noise_std',
                                                  'dampers_enabled')}
    assert node.pacer.real_time_factor == p['real_time_factor'], (where, p)
    assert node.live.noise_std == p['noise_std'], (where, p)
    assert node.live.dampers_enabled == p['dampers_enabled'], (where, p)


def _check_accepted(node, name, pv, descriptors, where):
    """A parameter the node accepted: declared, writable, of its declared type, in range."""
    assert name in descriptors, f'{where}: undeclared {name!r} accepted'
    d = descriptors[name]
    value = fz.python_value(pv)
    assert not d.read_only, f'{where}: read-only {name!r} changed'
    assert pv.type == d.type, f'{where}: {name!r} of type {d.type} took type {pv.type}'
    if pv.type == ParameterType.PARAMETER_DOUBLE:
        for r in d.floating_point_range:   # strictly: rclpy alone admits 1e-6 outside
            assert math.isfinite(value) and r.from_value <= value <= r.to_value, (where, value)
    if pv.type == ParameterType.PARAMETER_INTEGER:
        for r in d.integer_range:
            assert r.from_value <= value <= r.to_value, (where, value)
    if name in PARAMETERS:
        assert check(name, value) is None, (where, value)


def _apply_results(node, params, results, expected, descriptors, unnamed, where):
    """Check per-parameter results (SetParameters) and update the expected values."""
    assert len(results) == len(params), f'{where}: {len(results)} results for {len(params)}'
    for k, (prm, result) in enumerate(zip(params, results)):
        at = f'{where} #{k} {prm.name[:40]!r} type {prm.value.type}'
        if result.successful:
            _check_accepted(node, prm.name, prm.value, descriptors, at)
            expected[prm.name] = fz.python_value(prm.value)
        else:
            assert _one_line(result.reason), f'{at}: reason {result.reason!r}'
            if not _names_it(prm.name, result.reason):
                assert not prm.name, (
                    f'{at}: the refusal does not name the parameter: {result.reason!r}')
                unnamed[result.reason.split(',')[0][:40]] += 1


def _value(node, name):
    """A declared parameter's value (None for one declared without a value, 'overrides'
    unset: ``get_parameter`` raises for those)."""
    return node._parameters[name].value


def _assert_values(node, expected, where):
    names = set(node.list_parameters([], 0).names)
    assert names == set(expected), f'{where}: declared parameters changed: {names ^ set(expected)}'
    for name, value in expected.items():
        got = _value(node, name)
        assert fz.same_value(got, value), f'{where}: {name} = {got!r}, expected {value!r}'


def test_parameters_of_every_type(ros_context, scale):
    """Every declared parameter x every parameter type (0-9 and invalid 10, 200, 255), alone
    and in random batches (plain and atomic), with hostile values: each result is either a
    success leaving a value of the declared type inside the descriptor's closed range, or a
    one-line refusal naming the parameter that
    changes nothing (an atomic batch: all or nothing); every in-range value of a writable
    parameter is accepted; the node's state follows its parameters, it steps after every
    request (sim time as the factor says, to one sample period; samples finite) and
    /diagnostics never says ERROR; a tiny factor (1e-6, 5e-324) then 1.0 steps at once;
    GetParameters answers one value per declared name asked."""
    rng = _rng('parameters', scale)
    node = make_node(ros_context, 'sdof')
    stepper = Stepper(node)
    set_one, set_atomic = _service(node, 'set_parameters'), _service(
        node, 'set_parameters_atomically')
    names = list(node.list_parameters([], 0).names)
    assert set(PARAMETERS) <= set(names)
    descriptors = dict(zip(names, node.describe_parameters(names)))
    expected = {n: _value(node, n) for n in names}
    strangers = ['', '\x00', 'no_such', 'a' * 300, 'é', '/x.y', 'real_time_factor.',
                 'REAL_TIME_FACTOR', ' real_time_factor', 'qos_overrides./x.publisher.depth']
    counts, unnamed = Counter(), Counter()
    types = [*fz.PARAMETER_TYPES, *fz.INVALID_TYPES]
    try:
        # 1. each declared parameter with each type, alone
        for name in names:
            for ptype in types:
                for rep in range(scale):
                    where = f'alone {name} type {ptype} rep {rep}'
                    params = [ParameterMsg(name=name, value=fz.parameter_value(
                        rng, ptype, descriptors[name]))]
                    res = set_one(SetParameters.Request(parameters=params),
                                  SetParameters.Response())
                    _apply_results(node, params, res.results, expected, descriptors, unnamed,
                                   where)
                    counts['accepted' if res.results[0].successful else 'refused'] += 1
                    _assert_values(node, expected, where)
                    _state_matches_parameters(node, where)
                    stepper.advance(where)
        # 1b. each writable parameter of the node with in-range values of its type: all
        #     accepted (rclpy's use_sim_time: test_use_sim_time_is_not_an_unknown_parameter)
        for name in PARAMETERS:
            d = descriptors[name]
            if d.read_only:
                continue
            for rep in range(5 * scale):
                pv = fz.valid_value(rng, d)
                where = f'valid {name} = {fz.python_value(pv)!r} rep {rep}'
                res = set_one(SetParameters.Request(parameters=[ParameterMsg(
                    name=name, value=pv)]), SetParameters.Response())
                assert res.results[0].successful, (where, res.results[0].reason)
                _check_accepted(node, name, pv, descriptors, where)
                expected[name] = fz.python_value(pv)
                counts['valid accepted'] += 1
                _assert_values(node, expected, where)
                _state_matches_parameters(node, where)
                stepper.advance(where)
        stepper.diagnostics_ok('after the single requests')
        # 2. random batches of 1-6 parameters, declared names and strangers
        for b in range(60 * scale):
            k = rng.choice([1, 2, 3, 6])
            params = []
            for j in range(k):
                name = rng.choice(names + names + strangers)
                # an invalid type number only first: the guard then refuses all and nothing
                # was applied (a later one: test_invalid_type_after_a_valid_parameter...)
                ptype = rng.choice(types if j == 0 else list(fz.PARAMETER_TYPES))
                params.append(ParameterMsg(name=name, value=fz.parameter_value(
                    rng, ptype, descriptors.get(name))))
            where = f'batch {b}'
            if rng.random() < 0.5:
                res = set_one(SetParameters.Request(parameters=params), SetParameters.Response())
                _apply_results(node, params, res.results, expected, descriptors, unnamed,
                               where)
                counts['batch'] += 1
            else:
                before = dict(expected)
                res = set_atomic(SetParametersAtomically.Request(parameters=params),
                                 SetParametersAtomically.Response())
                result = res.result
                if result.successful:
                    counts['atomic batch accepted'] += 1
                    for prm in params:
                        _check_accepted(node, prm.name, prm.value, descriptors, where)
                        expected[prm.name] = fz.python_value(prm.value)
                else:
                    assert _one_line(result.reason), (where, result.reason)
                    if not any(_names_it(p.name, result.reason) for p in params):
                        assert not all(p.name for p in params), (where, result.reason)
                        unnamed[result.reason.split(',')[0][:40]] += 1
                    expected = before   # all or nothing
                counts['atomic batch'] += 1
            _assert_values(node, expected, where)
            _state_matches_parameters(node, where)
            stepper.advance(where)
            stepper.diagnostics_ok(where)
        # 3. the in-process API with Python values (numpy scalars, tuples, bytes too)
        python_values = [True, 0, -1, 2**63 - 1, math.nan, math.inf, -0.0, 5e-324, 1e-6, 0.5,
                         999.9999, np.float64(2.5), np.int64(3), '', 'x' * 10_000,
                         [1.0, math.nan], [True], ['a'], [1, 2], b'\x00\xff', (1.5,)]
        for _ in range(20 * scale):
            name = rng.choice(names)
            value = rng.choice(python_values)
            where = f'python {name} = {value!r:.40}'
            try:
                prm = Parameter(name, value=value)
            except (TypeError, ValueError):
                counts['not a parameter value (rclpy.Parameter refuses it)'] += 1
                continue
            result = node.set_parameters([prm])[0]
            pv = prm.get_parameter_value()
            if result.successful:
                _check_accepted(node, name, pv, descriptors, where)
                expected[name] = fz.python_value(pv)
            else:
                assert _one_line(result.reason), (where, result.reason)
            _assert_values(node, expected, where)
            _state_matches_parameters(node, where)
            stepper.advance(where)
        # 4. the regressions: a tiny factor, then 1.0 again, keeps producing output at once
        for tiny in (1e-6, 5e-324, 2.2250738585072014e-308):
            where = f'real_time_factor {tiny!r} then 1.0'
            for value in (tiny, 1.0):
                result = node.set_parameters([Parameter('real_time_factor', value=value)])[0]
                assert result.successful or (value == tiny and _one_line(result.reason)), where
                if result.successful:
                    expected['real_time_factor'] = value
                _assert_values(node, expected, where)
                stepper.advance(where)
            node._wall.now += 0.1
            t0 = node.live.t
            node.tick()
            assert node.live.t - t0 == pytest.approx(0.1, abs=stepper.period + 1e-9), where
            stepper.diagnostics_ok(where)
        # 5. reads: one value per declared name asked (unset 'overrides' included, issue 29
        #    'Smaller'), of the value's type; a request naming an undeclared one gets none
        get = _service(node, 'get_parameters')
        for _ in range(10 * scale):
            asked = rng.sample(names, rng.randint(1, len(names)))
            stranger = rng.random() < 0.3
            if stranger:
                asked.insert(rng.randrange(len(asked) + 1), rng.choice(strangers[2:]))
            res = get(GetParameters.Request(names=asked), GetParameters.Response())
            if stranger:
                assert len(res.values) == 0, (asked, res.values)
                continue
            assert len(res.values) == len(asked), (asked, len(res.values))
            for name, value in zip(asked, res.values):
                assert fz.same_value(fz.python_value(value), expected[name]), (name, value)
    finally:
        node.destroy_node()
    assert counts['valid accepted'] >= 20 and counts['refused'] > 200, counts
    assert stepper.samples > 0
    print(f'\nparameters: {dict(counts)}; rclpy refusals not naming the parameter: '
          f'{dict(unnamed)}; {stepper.samples} samples stepped')


def test_real_time_factor_fuzz_with_the_stepping_thread(ros_context, scale):
    """The stepping thread itself (it died on 5e-324 and slept 1e4 s on 1e-6): random factors
    in quick succession, the tiny ones included; after 1.0 is set again the stream resumes
    (the thread's longest wait is made endless here, so only the new factor's wake-up can
    resume it; how soon is a wall-clock figure, not asserted) and the thread is alive.

    A subscriber is matched (never spun): without one the node publishes what it steps at
    once instead of at its time, and never waits long."""
    from sensor_msgs.msg import Imu
    rng = _rng('rtf-thread', scale)
    node = VibrationNode(context=ros_context, parameter_overrides=[
        Parameter('scene', value='sdof')])
    listener = Node('listener', context=ros_context)
    listener.create_subscription(Imu, node.publishing.accel[0].topic, lambda m: None,
                                 itf.SENSOR_QOS)
    end = time.monotonic() + 10.0
    while not node.publishing.accel[0].has_subscribers() and time.monotonic() < end:
        time.sleep(0.05)
    assert node.publishing.accel[0].has_subscribers()
    node.MAX_WAIT = 1e6   # no periodic re-read: only a wake ends a long wait
    values = [1e-6, 5e-324, 2.2250738585072014e-308, 0.0, 1e-300, 0.5, 1000.0, 1.0, 1e-3]
    # random factors, then the sequence (1.0 running, a tiny one, 1.0 again)
    sequence = [(rng.choice(values), rng.choice([0.0, 0.01, 0.05, 0.2]))
                for _ in range(8 * scale)] + [(1.0, 0.3), (rng.choice([1e-6, 5e-324]), 0.3)]
    try:
        time.sleep(0.2)
        for k, (value, pause) in enumerate(sequence):
            result = node.set_parameters([Parameter('real_time_factor', value=value)])[0]
            assert result.successful, (k, value, result.reason)
            time.sleep(pause)
            assert node._thread.is_alive(), (k, value)
        assert node.set_parameters([Parameter('real_time_factor', value=1.0)])[0].successful
        t0 = node.live.t
        end = time.monotonic() + 20.0   # a deadline, not a figure: the machine may be busy
        while node.live.t - t0 <= 0.5 and time.monotonic() < end:
            time.sleep(0.01)
        assert node._thread.is_alive()
        assert node.live.t - t0 > 0.5, (f'{node.live.t - t0:.3f} s of sim time in 20 s after '
                                        f'the sequence {sequence}')
        assert node.live.failure is None, node.live.failure
        node.publish_diagnostics()
        assert node.last_diagnostics['level'] in (0, 1), node.last_diagnostics['message']
    finally:
        listener.destroy_node()
        node.destroy_node()


# --------------------------------------------------------------------------- command floods

def _random_message(rng, msg_type):
    """A message of ``msg_type`` with every field hostile (doubles, ints, strings, arrays)."""
    msg = msg_type()
    for field, kind in msg.get_fields_and_field_types().items():
        if kind in ('double', 'float'):
            value = fz.hostile_double(rng)
            if kind == 'float' and math.isfinite(value) and abs(value) > 3.4e38:
                value = math.copysign(math.inf, value)
            setattr(msg, field, float(value))
        elif kind == 'boolean':
            setattr(msg, field, rng.random() < 0.5)
        elif kind == 'string':
            setattr(msg, field, fz.hostile_string(rng).replace('\x00', ''))
        elif kind.startswith(('int', 'uint')):
            bits = int(kind.lstrip('uint') or 32)
            lo, hi = (0, 2**bits - 1) if kind.startswith('u') else (-2**(bits - 1),
                                                                     2**(bits - 1) - 1)
            setattr(msg, field, rng.choice([lo, hi, 0, 1]))
    return msg


def _float64_value(rng):
    if rng.random() < 0.3:
        return rng.uniform(0.0, 4000.0)
    if rng.random() < 0.3:
        return rng.choice([0.0, 1.0, 100.0, 10000.0, 1e5, 1e5 + 1e-9])
    return fz.hostile_double(rng)


def test_command_floods(ros_context, scale):
    """Thousands of commands with random values (NaN, inf, huge, negative, subnormal) on every
    topic the node subscribes to, through the subscription callbacks, then a burst over the
    wire: no callback raises, every invalid one is refused (counted in ``rejected`` and
    logged in one line), the last valid command is in force, the state stays finite and the
    node keeps stepping."""
    rng = _rng('commands', scale)
    node = make_node(ros_context, 'hpotp', LINEAR_HPOTP, speed_rate_limit=1e6)
    stepper = Stepper(node)
    logged = []
    original_log = node._log
    node._log = lambda level, text, *a, **k: (logged.append((level, text)),
                                              original_log(level, text, *a, **k))[1]
    subs = {s.topic_name: s for s in node.subscriptions}
    # the command topics this probe knows how to judge; any other one gets the generic checks
    state = {'/' + itf.SPEED_COMMAND: (lambda: node.live.profile.target, node.live.max_speed),
             '/' + itf.UNBALANCE_COMMAND: (lambda: node.live.unbalance.multiplier,
                                           node.live.max_unbalance)}
    assert set(state) <= set(subs), subs
    last = {topic: get() for topic, (get, _) in state.items()}
    n_per_topic = 2000 * scale
    invalid = 0
    try:
        for k in range(n_per_topic * len(subs)):
            topic = rng.choice(sorted(subs))
            sub = subs[topic]
            if sub.msg_type is Float64:
                value = _float64_value(rng)
                msg = Float64(data=value)
            else:
                msg = _random_message(rng, sub.msg_type)
            applied = sub.callback(msg)   # raising here would stop an executor: it must not
            if topic not in state:   # the fault command (a String): its callback says
                invalid += applied is False
            else:
                get, high = state[topic]
                if math.isfinite(value) and 0.0 <= value <= high:
                    last[topic] = value
                else:
                    invalid += 1
                assert get() == last[topic], (k, topic, value, get(), last[topic])
            if k % 500 == 0:
                stepper.advance(f'flood message {k}')
        assert node.rejected == invalid, (node.rejected, invalid)
        speed, rate, x = node.live.rotor_state()
        assert all(math.isfinite(v) for v in (speed, rate, x, node.live.t))
        assert 0.0 <= speed <= node.live.max_speed and 0.0 <= x <= node.live.max_unbalance
        warnings = [text for level, text in logged if level != 'info']
        assert len(warnings) == invalid   # each refusal is logged (throttled downstream)
        assert all(_one_line(text) and text.startswith('rejected: ') for text in warnings), [
            t for t in warnings if not (_one_line(t) and t.startswith('rejected: '))][:3]
        stepper.diagnostics_ok('after the flood')
        # a burst over the wire, as fast as rclpy publishes, then one good command: the good
        # one is applied (the reliable keep-last-10 queue may drop some of the burst)
        sender = Node('flooder', context=ros_context)
        ex = SingleThreadedExecutor(context=ros_context)
        ex.add_node(node)
        ex.add_node(sender)
        try:
            pubs = {t: sender.create_publisher(Float64, t, itf.COMMAND_QOS) for t in state}
            _spin(ex, 0.3)
            rejected = node.rejected
            for _ in range(500 * scale):
                for pub in pubs.values():
                    pub.publish(Float64(data=fz.hostile_double(rng) * -1.0 - 1.0))
            good = {'/' + itf.SPEED_COMMAND: 1234.5, '/' + itf.UNBALANCE_COMMAND: 2.5}
            for topic, pub in pubs.items():
                pub.publish(Float64(data=good[topic]))
            end = time.monotonic() + 10.0
            while any(state[t][0]() != good[t] for t in good) and time.monotonic() < end:
                ex.spin_once(timeout_sec=0.01)
            assert all(state[t][0]() == good[t] for t in good), {t: state[t][0]() for t in good}
            assert node.rejected > rejected
        finally:
            ex.shutdown(timeout_sec=1.0)
            sender.destroy_node()
        stepper.advance('after the wire burst')
        assert node.live.failure is None
    finally:
        node._log = original_log
        node.destroy_node()
    print(f'\ncommands: {n_per_topic * len(subs)} by callback ({invalid} invalid), '
          f'{1000 * scale} over the wire; topics {sorted(subs)}')


def _spin(executor, seconds):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.02)


# --------------------------------------------------------------------------- type clashes

def test_type_clashing_peers(ros_context, scale):
    """A peer publishes and subscribes with the wrong type on every topic name of the node
    (its commands and its outputs): DDS does not match them, nothing reaches the node's
    callbacks, the node keeps stepping and publishing its own types, and a command of the
    right type sent afterwards still works.

    The peer lives in a second rclpy context on the same domain: within one context (one DDS
    participant) the middleware refuses to create an endpoint whose type clashes with an
    existing one ("create_publisher() called for existing topic name ... with incompatible
    type"), so a clash needs a second participant, as a separate process would have.
    """
    from geometry_msgs.msg import Vector3Stamped
    from sensor_msgs.msg import Imu
    from std_msgs.msg import Bool, Float64MultiArray, Int32, String
    rng = _rng('types', scale)
    node = make_node(ros_context, 'hpotp', LINEAR_HPOTP, speed_rate_limit=1e6)
    stepper = Stepper(node)
    peer_ctx = rclpy.Context()
    rclpy.init(context=peer_ctx, domain_id=ros_context.get_domain_id())
    peer = Node('clasher', context=peer_ctx)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    ex_peer = SingleThreadedExecutor(context=peer_ctx)
    ex_peer.add_node(peer)

    def spin(seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.005)
            ex_peer.spin_once(timeout_sec=0.005)

    wrong_types = [String, Int32, Bool, Imu, Float64MultiArray, Vector3Stamped, Float64]
    own = dict(node.get_publisher_names_and_types_by_node(node.get_name(), '/'))
    own_subs = dict(node.get_subscriber_names_and_types_by_node(node.get_name(), '/'))
    topics = {t: types for t, types in (own | own_subs).items() if not t.startswith(
        ('/rosout', '/parameter_events'))}
    assert len(topics) >= 8, topics
    clashes, got = [], Counter()
    try:
        for topic, types in sorted(topics.items()):
            wrong = next(t for t in rng.sample(wrong_types, len(wrong_types))
                         if _type_name(t) not in types)
            clashes.append((topic, _type_name(wrong),
                            peer.create_publisher(wrong, topic, 10),
                            peer.create_subscription(wrong, topic,
                                                     lambda m, t=topic: got.update([t]), 10)))
        end = time.monotonic() + 10.0   # discovery: the node's graph shows both types
        while time.monotonic() < end and not all(
                len(dict(node.get_topic_names_and_types()).get(t, ())) >= 2 for t in topics):
            spin(0.1)
        seen = dict(node.get_topic_names_and_types())
        assert all(len(seen[t]) >= 2 for t in topics), {t: seen.get(t) for t in topics}
        rejected = node.rejected
        for k in range(20 * scale):
            for _, _, pub, _ in clashes:
                pub.publish(_random_message(rng, pub.msg_type))
            spin(0.01)
            if k % 5 == 0:
                stepper.advance(f'clash round {k}')
        spin(0.3)
        assert node.rejected == rejected, 'a wrong-typed message reached a command callback'
        assert node.live.profile.target == node.live.profile.target   # not NaN
        for topic in topics:   # the node's own endpoints are unchanged
            mine = [i for i in node.get_publishers_info_by_topic(topic)
                    + node.get_subscriptions_info_by_topic(topic)
                    if i.node_name == node.get_name()]
            assert mine and all(i.topic_type in topics[topic] for i in mine), topic
        # the right type, from the node's own context, still works
        sender = Node('sender', context=ros_context)
        ex.add_node(sender)
        good = sender.create_publisher(Float64, '/' + itf.SPEED_COMMAND, itf.COMMAND_QOS)
        end = time.monotonic() + 10.0
        while node.live.profile.target != 777.0 and time.monotonic() < end:
            good.publish(Float64(data=777.0))
            spin(0.05)
        assert node.live.profile.target == 777.0
        stepper.advance('after the clashes')
        stepper.diagnostics_ok('after the clashes')
        sender.destroy_node()
    finally:
        ex_peer.shutdown(timeout_sec=1.0)
        ex.shutdown(timeout_sec=1.0)
        peer.destroy_node()
        rclpy.try_shutdown(context=peer_ctx)
        node.destroy_node()
    print(f'\ntype clashes: {len(clashes)} wrong-typed publishers and as many subscribers '
          f'({", ".join(f"{t}:{w}" for t, w, _, _ in clashes)}); wrong-typed messages received '
          f'by the peer: {sum(got.values())}')


def _type_name(msg_type):
    module = msg_type.__module__.split('.')[0]
    return f'{module}/msg/{msg_type.__name__}'


# --------------------------------------------------------------------------- scene files

#: CPU seconds the loader may spend on one scene file (an alias bomb of 457 bytes took 200 s):
#: 2 s plus 20 s per MiB of file (5,000 impactors, 0.46 MiB, load in 6.4 s on a 2-core box)
LOAD_BUDGET_S = (2.0, 20.0)
#: CPU seconds (this process's) `study simulate` may spend on a mutated 50 ms scene: CPU
#: time, not wall time, so that another job on the machine does not fail the test
SIMULATE_BUDGET_S = 20.0


def _study(argv, capsys):
    """Run ``study`` in-process: (exit status, stdout, stderr); an exception is a failure."""
    capsys.readouterr()
    try:
        rc = study_main(argv)
    except BaseException as exc:   # a traceback: what the probe found
        out, err = capsys.readouterr()
        raise AssertionError(f'study {" ".join(argv)[:200]} raised {type(exc).__name__}: '
                             f'{str(exc)[:300]}') from exc
    out, err = capsys.readouterr()
    return rc, out, err


def _check_error_message(err, prefix, where, indented=True):
    """A refusal: one message, its first line starting with ``prefix``; further lines (one per
    further problem of a scene, as documented) indented (``study``) or at least not another
    message (the node prints the scene error's lines as they are); no traceback."""
    lines = err.rstrip('\n').split('\n')
    assert err.strip() and lines[0].startswith(prefix), f'{where}: {err[:500]!r}'
    assert 'Traceback' not in err, f'{where}: {err[:2000]}'
    if indented:
        assert all(line.startswith('  ') for line in lines[1:]), f'{where}: {err[:1000]!r}'
    else:
        assert not any(line.startswith(prefix) for line in lines[1:]), f'{where}: {err[:1000]!r}'
    return len(lines)


@contextlib.contextmanager
def _deadline(seconds):
    """Shut the default rclpy context down after ``seconds`` (a node that should have refused
    its scene would otherwise spin for good)."""
    timer = threading.Timer(seconds, lambda: rclpy.try_shutdown())
    timer.start()
    try:
        yield
    finally:
        timer.cancel()


def test_bad_scene_files(tmp_path, capsys, scale):
    """Random mutations of a valid scene file (byte flips, truncation, nesting up to 20,000
    deep, alias bombs, huge numbers, wrong types, unknown keys, non-UTF-8, YAML tags, extra
    documents, thousands of items) through the loader, ``study simulate`` and the node's
    console entry point: each is accepted or refused with exit 2 (3 for a run that diverges)
    and one message, never a traceback, within LOAD_BUDGET_S CPU s to load (linear in the
    file's size) and SIMULATE_BUDGET_S CPU s to simulate."""
    from impact_damper_sim.scene.build import load
    rng = _rng('scenes', scale)
    base = tmp_path / 'base.yaml'
    base.write_text(fz.BASE_SCENE)
    rc, out, err = _study(['simulate', str(base), '--json'], capsys)
    assert rc == 0, err   # the seed scene itself runs
    outcomes, lines_per_message, slowest = Counter(), Counter(), (0.0, '')
    for k in range(36 * scale):
        kind, content = fz.mutate_scene(rng, big=scale >= 10)
        path = tmp_path / f'case{k}.yaml'
        path.write_bytes(content)
        where = f'scene case {k} ({kind}, {len(content)} bytes, seed {SEED})'
        t0 = time.process_time()
        try:
            scene = load(str(path))
            refused = None
        except SceneError as exc:
            scene, refused = None, str(exc)
        except Exception as exc:
            raise AssertionError(f'{where}: the loader raised {type(exc).__name__}: '
                                 f'{str(exc)[:300]}') from exc
        cpu = time.process_time() - t0
        budget = LOAD_BUDGET_S[0] + LOAD_BUDGET_S[1] * len(content) / 2**20
        assert cpu < budget, f'{where}: loading took {cpu:.1f} CPU s (budget {budget:.1f} s)'
        if refused is not None:
            assert refused.strip() and 'Traceback' not in refused, where
        # study simulate (a long but valid run is only loaded: its time is the physics')
        steps = 0
        if scene is not None:
            sim = scene.scene['simulation']
            steps = sim['duration'] / sim['dt'] * (1 + len(scene.impactors))
        if steps <= 50_000:
            t0 = time.process_time()
            rc, out, err = _study(['simulate', str(path), '--json'], capsys)
            cpu_s = time.process_time() - t0
            assert cpu_s < SIMULATE_BUDGET_S, f'{where}: simulate took {cpu_s:.1f} CPU s'
            slowest = max(slowest, (cpu_s, where))
            assert rc in (0, 2, 3), f'{where}: exit {rc}: {err[:500]}'
            if rc == 0:
                result = json.loads(out)
                assert result['n_samples'] > 0, where
                assert 'Traceback' not in err, where
            else:
                lines_per_message[_check_error_message(err, 'study: error: ', where)] += 1
            assert (rc == 2) == (refused is not None) or rc == 3 or refused is None, (
                f'{where}: loader {"refused" if refused else "accepted"}, simulate exit {rc}: '
                f'{err[:300]}')
            outcomes[f'simulate exit {rc}'] += 1
        else:
            outcomes['valid, long: loaded only'] += 1
        # the node's console script refuses what the loader refuses (every other case)
        if refused is not None and k % 2 == 0:
            capsys.readouterr()
            with _deadline(30.0):
                rc = vibration_node.main(['--ros-args', '-p', f'scene:={path}'])
            _, err = capsys.readouterr()
            assert rc == 2, f'{where}: vibration_node exit {rc}: {err[:500]}'
            _check_error_message(err, 'vibration_node: ', where, indented=False)
            outcomes['node exit 2'] += 1
        outcomes[kind.split(':')[0]] += 1
    print(f'\nscene files: {dict(outcomes)}; lines per refusal {dict(lines_per_message)}; '
          f'slowest simulate {slowest[0]:.2f} CPU s ({slowest[1]})')


# --------------------------------------------------------------------------- MCAP logs

@pytest.fixture(scope='module')
def small_log(tmp_path_factory):
    """A small live recording of the node (sdof, 0.3 s, 4 KiB chunks): its path, bytes, chunk
    table and message count. Made once per module."""
    from conftest import next_domain_id
    path = tmp_path_factory.mktemp('fuzz_log') / 'good.mcap'
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=next_domain_id())
    chunk_size = node_recording.RECORD_CHUNK_SIZE
    node_recording.RECORD_CHUNK_SIZE = 4096   # many chunks in a small file
    try:
        node = VibrationNode(context=ctx, start_stepping=False, clock=FakeClock(),
                             parameter_overrides=[Parameter('scene', value='sdof'),
                                                  Parameter('imu_rate', value=200.0),
                                                  Parameter('record', value=str(path))])
        try:
            for k in range(30):
                node._wall.now += 0.01
                node.tick()
                if k % 10 == 0:
                    node.publish_diagnostics()
                    node.on_speed_command(Float64(data=math.nan))   # recorded, rejected
        finally:
            node.destroy_node()
    finally:
        node_recording.RECORD_CHUNK_SIZE = chunk_size
        rclpy.try_shutdown(context=ctx)
    chunks = fz.chunk_table(path)
    total = sum(c['messages'] for c in chunks)
    assert len(chunks) >= 8 and total > 100, (len(chunks), total)
    return path, path.read_bytes(), chunks, total


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _bounded(fn, seconds, where):
    """Run ``fn`` in a thread; fail if it takes longer than ``seconds`` (a FIFO-like hang)."""
    box = {}

    def run():
        try:
            box['value'] = fn()
        except BaseException as exc:   # handed to the test thread
            box['error'] = exc

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(seconds)
    assert not t.is_alive(), f'{where}: still running after {seconds} s'
    if 'error' in box:
        raise box['error']
    return box.get('value')


def _read_back(path):
    from mcap.reader import make_reader
    with open(path, 'rb') as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        n = sum(1 for _ in reader.iter_messages(log_time_order=False))
    return summary, n


def test_broken_log_files(small_log, tmp_path, capsys, scale):
    """Random corruptions of a small live recording (byte flips, a byte flipped inside one
    chunk, truncation, zeroed, inserted, deleted and duplicated ranges, absurd record lengths
    and times, swapped chunks, appended garbage, a stripped end, another profile, garbage)
    through ``RosLog``, ``study report``, replay's ``prepare`` and ``study recover``: each
    is read or refused in one line naming the file (exit 2), within 10 s; recover keeps at
    least every message of the chunks before the first damaged byte and, for a byte flipped
    inside one chunk (the first, which holds every channel record, too), every message
    outside that chunk; the input is
    never changed and an existing output is never replaced without --overwrite."""
    from impact_damper_sim.ros.replay_plan import prepare
    from impact_damper_sim.studies.log_reader import LogError, RosLog
    _, blob, chunks, total = small_log
    rng = _rng('logs', scale)
    outcomes = Counter()
    for k in range(22 * scale):
        kind, data, first = fz.corrupt_log(rng, blob, chunks)
        src = tmp_path / f'c{k}.mcap'
        src.write_bytes(data)
        digest = _sha(src)
        intact = sum(c['messages'] for c in chunks if c['end'] <= first)
        where = f'log case {k} ({kind}, first damaged byte {first}, seed {SEED})'
        # RosLog
        try:
            _bounded(lambda src=src: RosLog(src), 10.0, where)
            outcomes['RosLog ok'] += 1
        except LogError as exc:
            assert _one_line(str(exc)) and str(src) in str(exc), f'{where}: {exc}'
            outcomes['RosLog refused'] += 1
        # study report
        rc, out, err = _bounded(lambda src=src: _study(['report', str(src), '--json'], capsys),
                                10.0, where)
        assert rc in (0, 2), f'{where}: report exit {rc}: {err[:500]}'
        if rc == 0:
            json.loads(out)
            assert all(line.startswith('study: warning: ') for line in err.splitlines()), (
                where, err[:500])
        else:
            assert _one_line(err) and err.startswith(f'study: error: {src}'), (where, err)
        outcomes[f'report exit {rc}'] += 1
        # replay's planning (every third case)
        if k % 3 == 0:
            try:
                _bounded(lambda src=src: prepare(src), 10.0, where)
                outcomes['prepare ok'] += 1
            except LogError as exc:
                assert _one_line(str(exc)), f'{where}: {exc}'
                outcomes['prepare refused'] += 1
        # study recover
        out_path = tmp_path / f'r{k}.mcap'
        rc, out, err = _bounded(lambda src=src, out_path=out_path: _study(
            ['recover', str(src), str(out_path), '--json'], capsys), 10.0, where)
        assert rc in (0, 2), f'{where}: recover exit {rc}: {err[:500]}'
        if rc == 0:
            report = json.loads(out)
            assert report['messages'] >= intact, (
                f'{where}: recovered {report["messages"]} messages, the intact prefix holds '
                f'{intact}')
            if kind.startswith('flip_in_chunk:'):
                c = chunks[int(kind.split(':')[1])]
                assert report['messages'] >= total - c['messages'], (
                    f'{where}: recovered {report["messages"]} of {total}; the broken chunk '
                    f'held {c["messages"]}')
            summary, n = _read_back(out_path)
            assert summary is not None and n == report['messages'], (where, n)
            # an existing output is not replaced without --overwrite
            kept = _sha(out_path)
            rc2, _, err2 = _study(['recover', str(src), str(out_path)], capsys)
            assert rc2 == 2 and 'exists' in err2 and _sha(out_path) == kept, (where, err2)
        else:
            assert _one_line(err) and err.startswith('study: error: '), (where, err)
            assert intact == 0, f'{where}: refused although {intact} messages were intact'
            assert not out_path.exists(), f'{where}: a refused recovery left {out_path}'
        outcomes[f'recover exit {rc}'] += 1
        # the output may not be the input, even through a link and with --overwrite
        link = tmp_path / f'link{k}.mcap'
        link.symlink_to(src)
        rc3, _, err3 = _study(['recover', str(src), str(link), '--overwrite'], capsys)
        assert rc3 == 2 and _one_line(err3), (where, err3)
        assert _sha(src) == digest, f'{where}: the input was changed'
        outcomes[kind.split(':')[0]] += 1
    print(f'\nlog files: {dict(outcomes)}')


# --------------------------------------------------------------------------- record toggles

def test_record_toggles_never_overwrite(ros_context, tmp_path, monkeypatch, scale):
    """Quick random start/stop cycles of ``~/record`` with automatic names and
    record_overwrite on (500 cycles overwrote 475 files before), then a second run in the same
    directory: every start names a new file, no file is replaced or lost, and each one is a
    finished, readable MCAP."""
    monkeypatch.chdir(tmp_path)
    rng = _rng('toggles', scale)
    started, stops, digests = [], 0, {}

    def toggle_run(n, run):
        nonlocal stops
        node = make_node(ros_context, 'sdof', record_overwrite=True)
        try:
            for k in range(n):
                where = f'run {run} toggle {k}'
                if rng.random() < 0.55:
                    recording = node.recorder is not None
                    before = set(os.listdir('.'))
                    res = node.on_record_request(SetBool.Request(data=True), SetBool.Response())
                    if recording:
                        assert not res.success and 'already recording' in res.message, where
                    else:
                        assert res.success, (where, res.message)
                        name = os.path.basename(res.message)
                        assert name not in before, f'{where}: {name} existed'
                        started.append(name)
                else:
                    recording = node.recorder is not None
                    res = node.on_record_request(SetBool.Request(data=False),
                                                 SetBool.Response())
                    assert res.success == recording and _one_line(res.message), (where, res)
                    stops += recording
                if rng.random() < 0.3:
                    node._wall.now += 0.01
                    node.tick()
        finally:
            node.destroy_node()   # finishes an open recording

    toggle_run(60 * scale, 1)
    first = list(started)
    digests = {name: _sha(tmp_path / name) for name in first}
    toggle_run(20 * scale, 2)
    assert len(started) == len(set(started)), Counter(started).most_common(3)
    assert sorted(p.name for p in tmp_path.glob('*.mcap')) == sorted(started)
    assert all(_sha(tmp_path / name) == d for name, d in digests.items()), 'run 2 replaced a file'
    for name in started:
        summary, n = _read_back(tmp_path / name)
        assert summary is not None and n >= 1, name   # finished, with the latched state
    # a fixed name without overwrite: refused once it exists, the file untouched
    node = make_node(ros_context, 'sdof', record='fixed.mcap')
    try:
        assert node.on_record_request(SetBool.Request(data=False), SetBool.Response()).success
        kept = _sha(tmp_path / 'fixed.mcap')
        for _ in range(5):
            res = node.on_record_request(SetBool.Request(data=True), SetBool.Response())
            assert not res.success and 'exists' in res.message and _one_line(res.message)
        assert _sha(tmp_path / 'fixed.mcap') == kept
    finally:
        node.destroy_node()
    print(f'\nrecord toggles: {len(started)} files started over 2 runs, {stops} stops, '
          'all distinct and readable')


# --------------------------------------------------------------------------- known defects

def test_invalid_type_after_a_valid_parameter_is_not_reported_as_refusing_both(ros_context):
    """SetParameters sets each parameter on its own: a valid one is applied and reported
    so, the unreadable one after it (type number 200) is refused alone, by name."""
    node = make_node(ros_context, 'sdof')
    try:
        from rcl_interfaces.msg import ParameterValue
        res = _service(node, 'set_parameters')(SetParameters.Request(parameters=[
            ParameterMsg(name='real_time_factor', value=ParameterValue(type=3, double_value=2.0)),
            ParameterMsg(name='noise_std', value=ParameterValue(type=200))]),
            SetParameters.Response())
        assert node.get_parameter('real_time_factor').value == 2.0
        assert node.pacer.real_time_factor == 2.0
        assert res.results[0].successful, res.results[0]
        assert not res.results[1].successful
        assert res.results[1].reason.startswith('noise_std: '), res.results[1].reason
    finally:
        node.destroy_node()


def test_known_refusals_name_the_parameter(ros_context):
    """rclpy's own refusals (a wrong type, NOT_SET, an undeclared name listed as '[]') and
    an unreadable type number name the parameter at fault, in an atomic request of two."""
    from rcl_interfaces.msg import ParameterValue
    node = make_node(ros_context, 'sdof')
    try:
        set_atomic = _service(node, 'set_parameters_atomically')
        for name, value in [('real_time_factor', ParameterValue(type=4, string_value='x')),
                            ('real_time_factor', ParameterValue(type=0)),
                            ('real_time_factor', ParameterValue(type=200)),
                            ('no_such', ParameterValue(type=3, double_value=1.0))]:
            res = set_atomic(SetParametersAtomically.Request(parameters=[
                ParameterMsg(name='noise_std', value=ParameterValue(type=3, double_value=1.0)),
                ParameterMsg(name=name, value=value)]),
                SetParametersAtomically.Response())
            assert not res.result.successful
            assert res.result.reason.startswith(f'{name}: '), res.result.reason
            assert node.get_parameter('noise_std').value == 0.0   # atomic: nothing applied
    finally:
        node.destroy_node()


def test_get_parameters_answers_every_declared_name(ros_context):
    """Issue 29 'Smaller': a GetParameters request naming 'overrides' (declared, unset)
    returned no value for any name in it; now one value per name, NOT_SET for the unset one
    (the fuzz's part 5 asks random subsets too)."""
    node = make_node(ros_context, 'sdof')
    try:
        names = list(node.list_parameters([], 0).names)
        res = _service(node, 'get_parameters')(GetParameters.Request(names=names),
                                               GetParameters.Response())
        assert len(res.values) == len(names), (len(res.values), len(names))
        unset = res.values[names.index('overrides')]
        assert unset.type == ParameterType.PARAMETER_NOT_SET
    finally:
        node.destroy_node()


def test_use_sim_time_is_not_an_unknown_parameter(ros_context):
    """rclpy declares use_sim_time writable on every node: the node accepts it (pacing runs
    on its own wall clock either way)."""
    node = make_node(ros_context, 'sdof')
    try:
        writable = not node.describe_parameter('use_sim_time').read_only
        result = node.set_parameters([Parameter('use_sim_time', value=True)])[0]
        assert result.successful or not writable, result.reason
        assert 'unknown parameter' not in result.reason, result.reason
    finally:
        node.destroy_node()


@pytest.mark.parametrize('tagged', ['!!int uy', '!!float abc', '!!bool maybe', '!!timestamp x'])
def test_a_mistyped_yaml_tag_is_a_scene_error(tmp_path, capsys, tagged):
    """A YAML tag whose constructor cannot convert the value raised ValueError, KeyError or
    AttributeError out of the scene loader (a traceback and exit 1 from study and the node);
    now one line naming the line and column, exit 2."""
    path = tmp_path / 'tag.yaml'
    path.write_text(fz.BASE_SCENE.replace('dof: uy\n', f'dof: {tagged}\n', 1))
    rc, _, err = _study(['simulate', str(path)], capsys)
    assert rc == 2 and _one_line(err), err


def test_recover_keeps_what_follows_a_broken_first_chunk(small_log, tmp_path):
    """The first chunk holds every schema and channel record (the recorder registers all
    topics at start): recover skipped every later message as of an 'unknown channel'; now it
    takes the channels from the summary and keeps every message outside the broken chunk."""
    from impact_damper_sim.recording import recover
    _, blob, chunks, total = small_log
    first = chunks[0]
    assert first['channels']   # where the recorder's channel records are
    data = bytearray(blob)
    data[(first['records'] + first['end']) // 2] ^= 0x55   # one byte inside its records
    src = tmp_path / 'first_chunk.mcap'
    src.write_bytes(bytes(data))
    report = recover(src, tmp_path / 'out.mcap')
    assert report.corrupt_chunks == 1
    assert report.messages >= total - first['messages'], (report.messages, total,
                                                          report.skipped_messages)


@pytest.mark.parametrize('char', ['\x08', '\x7f', '\x01'])
def test_a_control_character_is_a_scene_error(tmp_path, capsys, char):
    """A control character in a scene file (a flipped bit) raised yaml.reader.ReaderError from
    the loader's constructor, outside its YAML-error handling (a traceback and exit 1); now
    one line naming the character and its line and column, exit 2."""
    path = tmp_path / 'ctrl.yaml'
    path.write_text(fz.BASE_SCENE.replace('name: fuzz', f'name: fu{char}zz', 1))
    rc, _, err = _study(['simulate', str(path)], capsys)
    assert rc == 2 and _one_line(err), err


def test_a_broken_schema_is_one_line(small_log, tmp_path, capsys):
    """A broken schema text in the summary (a NUL in a '====' separator line) made study
    report print mcap_ros2's vendored rosidl parser's 'Error with: ...' before its one-line
    error (two lines, the first with a NUL); now one line, control characters escaped."""
    _, blob, _, _ = small_log
    data = bytearray(blob)
    schema = data.rfind(b'sensor_msgs/msg/PointCloud2')   # the summary section's copy
    separator = data.find(b'=' * 20, schema)
    assert schema > 0 and separator > 0
    data[separator + 10] = 0
    src = tmp_path / 'schema.mcap'
    src.write_bytes(bytes(data))
    rc, out, err = _study(['report', str(src)], capsys)
    assert rc == 2 and _one_line(err) and err.startswith('study: error: '), err
    assert not out.strip(), out   # the parser's own 'Error with:' line is not printed
    assert not any(ord(c) < 32 for c in err.rstrip('\n')), repr(err)   # escaped: \x00
