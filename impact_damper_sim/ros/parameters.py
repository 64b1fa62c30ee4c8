"""``vibration_node``'s parameters: declarations, ranges, and strict checks with clear messages.

One table, :data:`PARAMETERS`, gives each parameter's :class:`Spec`: default, description
(with unit), range and whether it can change at run time (rclpy refuses a change of a
read-only one before the node's callback runs). The node declares them with ranged
descriptors, and checks every value itself, strictly: rclpy's own range check admits values
within a relative 1e-6 of a bound (``1000.0001`` against 1000) and lets NaN through.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.parameter import Parameter

from ..integrate import simulation as _simulation
from ..recording import node_topics as _topics
from ..scene.schema import SceneError

#: integration methods the live node steps ('' = the scene's simulation.method): the
#: simulation's, but 'direct' (the live node steps the modal model)
METHODS = ('',) + tuple(m for m in _simulation.METHODS if m != 'direct')


class Spec(NamedTuple):
    """One parameter: its default (its type; ``Parameter.Type.STRING_ARRAY`` for a string
    array without one), description with unit, closed range ``(low, high)`` or None, and
    whether it is read-only (set at start only)."""

    default: object
    description: str
    bounds: tuple = None
    read_only: bool = False


#: name: Spec
PARAMETERS = {
    'scene': Spec('hpotp', 'scene name (config/scenes/<name>.yaml) or path to a scene file',
              None, True),
    'overrides': Spec(Parameter.Type.STRING_ARRAY,
                  "scene overrides 'key=value' (engineering units allowed, e.g. "
                  "'impactors.0.clearance=2 mil')", None, True),
    'method': Spec('', 'integration method: exact, newmark or newmark_step_end; empty = the '
                   "scene's simulation.method", None, True),
    'real_time_factor': Spec(1.0, 'sim seconds per wall second; 0 = as fast as possible '
                              '(dimensionless)', (0.0, 1000.0), False),
    'sample_rate': Spec(0.0, 'full-rate accelerometer sample rate (Hz) of accel/<name>/batch, '
                         ">= 100 and above twice every sensor's anti-alias cutoff; 0 = from "
                         'the scene: the lowest '
                         'submultiple of 1/simulation.dt at least 2.5 x the highest sensor '
                         'lowpass (hpotp 2000 Hz, rbs 20000 Hz), 2000 Hz without one',
                    (0.0, 100000.0), True),
    'imu_rate': Spec(0.0, 'rate of the per-sample Imu stream accel/<name> (Hz): the full-rate '
                      'signal (accel/<name>/batch) decimated through an anti-alias FIR, '
                      'sample_rate / k for a whole number k from 1 to 2000 (so at least '
                      'sample_rate / 2000: 1 Hz from 2 kHz); 0 = the highest such rate not '
                      'above 1000 Hz (hpotp 1000 Hz from 2000 Hz, rbs 1000 Hz from 20000 Hz)',
                 (0.0, 100000.0), True),
    'imu_group': Spec(4, 'Imu samples per accelerometer the node sends together, each with '
                      'its own stamp and none more than imu_group - 1 ms + 0.2 ms early '
                      '(dimensionless): 4 = a group every 4 ms at 1 kHz; 1 = each sample at '
                      'its own time (four times the wake-ups, more CPU); at most 4, so a '
                      "keep-last-5 reader holds a whole group", (1, 4), True),
    'dampers_enabled': Spec(True, 'impact dampers act (dynamic: compare with and without live)',
                        None, False),
    'noise_std': Spec(0.0, 'white noise added to each acceleration sample, standard deviation '
                       '(m/s^2)', (0.0, 1000.0), False),
    'noise_seed': Spec(0, 'seed of the noise generator and, at start, of every random stage of '
                      'the accelerometer channel (sensor noise, biases, DAQ noise); setting '
                      'it live restarts the noise_std sequence only (dimensionless)',
                   (0, 2**31 - 1), False),
    'max_speed': Spec(0.0, 'largest accepted speed command (rad/s); 0 = twice the scene speed',
                  (0.0, 1.0e5), True),
    'max_unbalance': Spec(100.0, 'largest accepted unbalance multiplier X (dimensionless)',
                      (0.0, 1.0e4), True),
    'speed_rate_limit': Spec(0.0, "rate limit of speed changes (rad/s^2); 0 = the scene's "
                              '(ramp slope or max_rate; at run time: the rate at start); a '
                              'change also applies to a ramp under way (no effect without a '
                              'commanded rotor)', (0.0, 1.0e6), False),
    'hardware_id': Spec('', "hardware_id of the node's /diagnostics status, which a plant sets "
                        'to tell its machines apart (e.g. a pump serial); empty = the '
                        "namespace and the scene, e.g. 'pump3/hpotp' ('hpotp' at the root)",
                        None, True),
    'publish_clock': Spec(True, 'publish /clock (turn off on all but one node of a system)',
                      None, True),
    'publish_truth': Spec(False, "publish each accelerometer's ground truth accel/<name>/truth: "
                             "the model's acceleration (m/s^2) before the channel, through the "
                             'anti-alias low-pass only, in the batch layout (recorded when on); '
                             'off: a real test stand has none', None, True),
    'tick_period': Spec(_topics.TICK_PERIOD, 'sim time stepped per chunk (s); samples are '
                    'computed one to six chunks ahead (five stepped at a time) and published '
                    'by their own time (the Imu in groups of imu_group)',
                    _topics.TICK_PERIOD_RANGE, True),
    'state_period': Spec(_topics.STATE_PERIOD, 'period of the impactor_state republish (s); it '
                     'is also sent on every change', _topics.STATE_PERIOD_RANGE, True),
    'diagnostics_period': Spec(1.0, 'period of /diagnostics (s)', (0.1, 60.0), True),
    'max_lag': Spec(0.25, 'largest schedule deficit kept before it is dropped and reported (s)',
                (0.01, 10.0), True),
    'record': Spec('', 'MCAP file to record every published topic and received command to, in '
                   "rosbag2's layout; empty = not recording (start/stop at run time with the "
                   '~/record service)', None, True),
    'record_overwrite': Spec(False, 'overwrite an existing record file (otherwise refused)', None,
                         True),
    'schedule': Spec('', 'command schedule to play in sim time (YAML file: speed, speed_rate, '
                     'unbalance, dampers, noise_std, noise_seed, fault, clear_fault at given '
                     'times; docs/node.md); each applied entry is recorded as the command or '
                     "parameter change it stands for; empty = none", None, True),
}

#: parameters every rclpy node declares itself
RCLPY_PARAMETERS = ('use_sim_time', 'start_type_description_service')


class ParameterError(SceneError):
    """A start-up parameter is invalid; the message names it and its allowed values."""


def kind_of(default):
    """The parameter type name of a default: bool, int, double, string or string[]."""
    if isinstance(default, Parameter.Type):
        return 'string[]'
    if isinstance(default, bool):
        return 'bool'
    return {int: 'int', float: 'double', str: 'string'}[type(default)]


def parameters_markdown():
    """The parameter table of docs/node.md (markdown str), generated from :data:`PARAMETERS`."""
    rows = ['| parameter | type | default | range | dynamic | description |',
            '|---|---|---|---|---|---|']
    for name, (default, description, bounds, read_only) in PARAMETERS.items():
        kind = kind_of(default)
        if kind == 'string[]':
            shown = '(none)'
        elif kind == 'bool':
            shown = str(default).lower()
        else:
            shown = f'`{default}`' if default != '' else "''"
        span = f'{bounds[0]:g} .. {bounds[1]:g}' if bounds else ''
        rows.append(f"| `{name}` | {kind} | {shown} | {span} | {'no' if read_only else 'yes'} "
                    f'| {description} |')
    return '\n'.join(rows)


def descriptor(name):
    """The ``ParameterDescriptor`` of a parameter (description, range, read_only)."""
    default, description, bounds, read_only = PARAMETERS[name]
    desc = ParameterDescriptor(name=name, description=description, read_only=read_only)
    if bounds is not None:
        if isinstance(default, int) and not isinstance(default, bool):
            desc.integer_range = [IntegerRange(from_value=int(bounds[0]),
                                               to_value=int(bounds[1]), step=1)]
        else:
            desc.floating_point_range = [FloatingPointRange(
                from_value=float(bounds[0]), to_value=float(bounds[1]), step=0.0)]
    return desc


def expected(name):
    """What a parameter accepts, in words (for messages)."""
    spec = PARAMETERS[name]
    bounds, kind = spec.bounds, kind_of(spec.default)
    if name == 'method':
        return 'one of ' + ', '.join(repr(m) for m in METHODS)
    if name == 'sample_rate':
        return 'a double, 0 (from the scene) or in [100, 100000] Hz'
    if bounds is not None:
        fmt = (lambda v: str(int(v))) if kind == 'int' else (lambda v: f'{v:g}')
        return (f'{"an int" if kind == "int" else "a finite double"} in '
                f'[{fmt(bounds[0])}, {fmt(bounds[1])}]')
    return {'bool': 'a bool', 'string': 'a string', 'string[]': 'a string array'}[kind]


def check(name, value):
    """Why ``value`` is not valid for parameter ``name`` (str), or None when it is.

    Strict: the type must be the declared one (an int is not taken for a double, nor a
    double for an int), a double finite and inside its closed range.
    """
    if name not in PARAMETERS:
        return f'unknown parameter {name!r}'
    spec = PARAMETERS[name]
    bounds, kind = spec.bounds, kind_of(spec.default)
    ok_type = {'bool': lambda v: isinstance(v, bool),
               'int': lambda v: isinstance(v, int) and not isinstance(v, bool),
               'double': lambda v: isinstance(v, float),
               'string': lambda v: isinstance(v, str),
               'string[]': lambda v: (isinstance(v, (list, tuple))
                                      and all(isinstance(s, str) for s in v))}[kind]
    if not ok_type(value):
        return f'{value!r} is not {expected(name)}'
    if kind == 'double' and not math.isfinite(value):
        return f'{value!r} is not {expected(name)}'
    if bounds is not None and not bounds[0] <= value <= bounds[1]:
        return f'{value!r} is not {expected(name)}'
    if name == 'sample_rate' and 0.0 < value < 100.0:
        return f'{value!r} is not {expected(name)}'
    if name == 'method' and value not in METHODS:
        return f'{value!r} is not {expected(name)}'
    if isinstance(value, str) and '\x00' in value:
        return 'a string with a NUL character'
    return None


def declare_all(node):
    """Declare every parameter on ``node`` and return the values (dict).

    Raises
    ------
    ParameterError
        A value given at start-up (``-p``, a params file or ``parameter_overrides``) is
        invalid: one line naming the parameter and what it accepts.
    """
    from rclpy.exceptions import ParameterException
    overrides = getattr(node, '_parameter_overrides', {})
    for name in PARAMETERS:
        given = overrides.get(name)
        kind = kind_of(PARAMETERS[name].default)
        if (given is not None and kind == 'double'
                and given.type_ == Parameter.Type.INTEGER):
            # '-p real_time_factor:=1' means 1.0: YAML reads it as an int
            given = overrides[name] = Parameter(name, value=float(given.value))
        if (given is not None and kind == 'string[]'
                and isinstance(given.value, (list, tuple)) and len(given.value) == 0):
            # rclpy reads an empty list as a byte array; empty means none: unset
            del overrides[name]
            given = None
        if given is not None and given.type_ != Parameter.Type.NOT_SET:
            why = check(name, given.value)
            if why:
                raise ParameterError(f'parameter {name!r}: {why}')
        try:
            node.declare_parameter(name, PARAMETERS[name].default, descriptor(name))
        except (ParameterException, TypeError, ValueError) as exc:   # what rclpy refuses
            raise ParameterError(f'parameter {name!r}: {exc}; expected '
                                 f'{expected(name)}') from None
    values = {}
    for name in PARAMETERS:
        value = node.get_parameter_or(name, Parameter(name, value=None)).value
        if value is not None:
            why = check(name, list(value) if isinstance(value, tuple) else value)
            if why:
                raise ParameterError(f'parameter {name!r}: {why}')
        values[name] = value
    unknown = sorted(set(overrides) - set(PARAMETERS) - set(RCLPY_PARAMETERS))
    serve_unset_parameters(node)
    return values, unknown


def serve_unset_parameters(node):
    """Make ``node``'s ``get_parameters`` service answer a declared but unset parameter.

    rclpy answers no values at all when one requested name is declared but unset
    (``overrides`` without overrides: a statically typed parameter has no default); ROS 2
    specifies one value per name, ``PARAMETER_NOT_SET`` for an unset one, which is what this
    answers. A name that is not declared keeps rclpy's answer (no values).
    """
    from rcl_interfaces.msg import ParameterValue
    from rcl_interfaces.srv import GetParameters
    from rclpy.exceptions import ParameterNotDeclaredException, ParameterUninitializedException

    def get_parameters(request, response):
        values = []
        for name in request.names:
            try:
                values.append(node.get_parameter(name).get_parameter_value())
            except ParameterUninitializedException:
                values.append(ParameterValue())   # type PARAMETER_NOT_SET
            except ParameterNotDeclaredException:
                values = []
                break
        response.values = values
        return response

    own = f'{node.get_name()}/get_parameters'   # as rclpy's ParameterService names it
    for service in node.services:
        if service.srv_type is GetParameters and service.srv_name == own:
            service.callback = get_parameters


__all__ = ['METHODS', 'PARAMETERS', 'ParameterError', 'Spec', 'check', 'declare_all',
           'descriptor', 'expected', 'parameters_markdown', 'serve_unset_parameters']
