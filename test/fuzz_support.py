"""Generators for test_fuzz_probe.py: hostile parameter values, scene-file mutations and MCAP
corruptions, each drawn from a seeded ``random.Random`` so that a failing case reproduces
from its seed and index alone.

Nothing here imports rclpy at module level: the scene and log generators work without ROS.
"""
from __future__ import annotations

import math
import struct

# --- values -----------------------------------------------------------------------------------

#: doubles a hostile peer sends: non-finite, signed zero, subnormal, extremes, near-bounds
HOSTILE_DOUBLES = (math.nan, -math.nan, math.inf, -math.inf, 0.0, -0.0, 5e-324, -5e-324,
                   2.2250738585072014e-308, 1e-300, 1e-9, 1e-6, 0.5, 1.0, 1000.0, 1000.0001,
                   1e5, 1e6, 1e9, 1e308, -1e308, 1.7976931348623157e308, -1.0, -1e-300, 2.0**53)
#: 64-bit integers around every boundary a parameter may have
HOSTILE_INTS = (0, 1, -1, 7, 255, 2**31 - 1, 2**31, -2**31, -2**31 - 1, 2**32, 2**53 + 1,
                2**63 - 1, -2**63)
#: strings: empty, NUL, huge, unicode (combining, astral, RTL), paths, YAML and scene names
HOSTILE_STRINGS = ('', '\x00', 'a\x00b', ' ', '\n', 'x' * 100_000, 'é' * 1000,
                   '\u202e\U0001f4a9\u0301\ufeff', '\U0010ffff', 'sdof', 'hpotp', 'rbs', 'exact',
                   'newmark', 'direct', '/dev/zero', '/nonexistent/x.yaml', '../../etc/passwd',
                   '{a: [1, 2]}', '*alias', '!!python/object/apply:os.system [true]', 'true',
                   '1e309', 'nan', '~')


def hostile_double(rng, bounds=None):
    """A double: from :data:`HOSTILE_DOUBLES`, or around/inside ``bounds`` (lo, hi)."""
    if bounds is not None and rng.random() < 0.5:
        lo, hi = bounds
        return rng.choice([lo, hi, math.nextafter(lo, -math.inf), math.nextafter(hi, math.inf),
                           hi * (1 + 1e-7), lo + (hi - lo) * rng.random(),
                           lo + (hi - lo) * rng.random() ** 8])
    return rng.choice(HOSTILE_DOUBLES)


def hostile_int(rng, bounds=None):
    if bounds is not None and rng.random() < 0.5:
        lo, hi = bounds
        return rng.choice([lo, hi, lo - 1, hi + 1, rng.randint(lo, hi)])
    return rng.choice(HOSTILE_INTS)


def hostile_string(rng):
    if rng.random() < 0.2:
        return ''.join(chr(rng.choice([rng.randint(32, 126), rng.randint(0x80, 0xd7ff),
                                       rng.randint(0xe000, 0x10ffff)]))
                       for _ in range(rng.randint(0, 40)))
    return rng.choice(HOSTILE_STRINGS)


#: ROS parameter types by number (rcl_interfaces/msg/ParameterType); 10, 200, 255 are invalid
PARAMETER_TYPES = {0: 'not_set', 1: 'bool', 2: 'integer', 3: 'double', 4: 'string',
                   5: 'byte_array', 6: 'bool_array', 7: 'integer_array', 8: 'double_array',
                   9: 'string_array'}
INVALID_TYPES = (10, 200, 255)


def parameter_value(rng, ptype, descriptor=None):
    """A ``rcl_interfaces/ParameterValue`` of type number ``ptype`` with a hostile value.

    Every field is filled (a real peer may send junk in the fields its type does not use);
    ``descriptor`` (rcl_interfaces/ParameterDescriptor), when given, aims some values at its
    range bounds.
    """
    from rcl_interfaces.msg import ParameterValue
    fbounds = ibounds = None
    if descriptor is not None and descriptor.floating_point_range:
        r = descriptor.floating_point_range[0]
        fbounds = (r.from_value, r.to_value)
    if descriptor is not None and descriptor.integer_range:
        r = descriptor.integer_range[0]
        ibounds = (r.from_value, r.to_value)
    v = ParameterValue(type=ptype)
    v.bool_value = rng.random() < 0.5
    v.integer_value = hostile_int(rng, ibounds)
    v.double_value = float(hostile_double(rng, fbounds))
    v.string_value = hostile_string(rng)
    n = rng.choice([0, 1, 2, 5, 1000])
    v.byte_array_value = [bytes([rng.randrange(256)]) for _ in range(n)]
    v.bool_array_value = [rng.random() < 0.5 for _ in range(n)]
    v.integer_array_value = [hostile_int(rng) for _ in range(n)]
    v.double_array_value = [float(hostile_double(rng)) for _ in range(n)]
    v.string_array_value = [rng.choice(['impactors.0.cor=0.6', 'impactors=[]', '=', 'a=b',
                                        hostile_string(rng)]) for _ in range(min(n, 20))]
    return v


def valid_value(rng, descriptor):
    """A ``ParameterValue`` of the descriptor's type inside its range (bool, int, double)."""
    from rcl_interfaces.msg import ParameterValue
    v = ParameterValue(type=descriptor.type)
    if descriptor.type == 1:
        v.bool_value = rng.random() < 0.5
    elif descriptor.type == 2:
        r = descriptor.integer_range[0] if descriptor.integer_range else None
        v.integer_value = rng.randint(r.from_value, r.to_value) if r else rng.randint(-9, 9)
    elif descriptor.type == 3:
        r = descriptor.floating_point_range[0] if descriptor.floating_point_range else None
        lo, hi = (r.from_value, r.to_value) if r else (-1.0, 1.0)
        v.double_value = rng.choice([lo, hi, lo + (hi - lo) * rng.random(),
                                     lo + (hi - lo) * rng.random() ** 6])
    else:
        raise ValueError(f'no valid-value generator for parameter type {descriptor.type}')
    return v


def python_value(pv):
    """The value a ParameterValue carries for its type (None for NOT_SET or an invalid type)."""
    field = {1: 'bool_value', 2: 'integer_value', 3: 'double_value', 4: 'string_value',
             5: 'byte_array_value', 6: 'bool_array_value', 7: 'integer_array_value',
             8: 'double_array_value', 9: 'string_array_value'}.get(pv.type)
    return None if field is None else getattr(pv, field)


def same_value(a, b):
    """Equal, with NaN equal to NaN and sequences compared item by item."""
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, (list, tuple)) or hasattr(a, 'tolist'):
        a = list(a.tolist() if hasattr(a, 'tolist') else a)
        b = list(b.tolist() if hasattr(b, 'tolist') else b)
        return len(a) == len(b) and all(same_value(x, y) for x, y in zip(a, b))
    return a == b


# --- scene files ------------------------------------------------------------------------------

#: a quick, valid SDOF scene: 50 ms at 0.1 ms (500 samples) per `study simulate`
BASE_SCENE = """\
name: fuzz
description: SDOF with an impact damper, the fuzz probe's seed scene
structure:
  kind: sdof
  mass: 2 kg
  natural_frequency: 25.16460605224352 Hz
  damping_ratio: 0.02
  dof: uy
modal:
  n_modes: 1
sensors:
  - {name: primary, node: 0, dof: uy}
forcing:
  - node: 0
    dof: uy
    amplitude: 10 N
    frequency_ratio: 1.0
impactors:
  - name: damper
    kind: sdof
    node: 0
    dof: uy
    mass_ratio: 0.10
    cor: 0.5
    clearance: 4.8 mm
simulation:
  method: exact
  dt: 0.1 ms
  duration: 50 ms
  window: 10 ms
"""

_WRONG_TYPED = ['[]', '{}', 'null', 'true', '[1, 2, 3]', '{x: 1}', '"text"', "''", '0x1F',
                '.nan', '-.inf', '.inf', '1e309', '-1e309', '5e-324', '1e308 kg',
                '99999999999999999999999999999999999999', '-0', '1_000', '0o777', '2001-12-14',
                '!!binary aGVsbG8=', '!!python/object/apply:os.system ["true"]', '&a 1', '*a',
                '? complex key', '|\n    block', '"\\uD800"', '4.8 furlongs', '4.8 mm mm',
                '-4.8 mm', '1e-320 s', '0 s', '1e-308 s', '1e9 s', '1e308 Hz', 'nan kg']


def _bomb(levels, width=10):
    lines = ['a0: &a0 [' + ', '.join(['x'] * width) + ']']
    for k in range(1, levels):
        lines.append(f'a{k}: &a{k} [' + ', '.join([f'*a{k - 1}'] * width) + ']')
    return '\n'.join(lines) + '\n', f'*a{levels - 1}'


def mutate_scene(rng, base=BASE_SCENE, big=False):
    """One mutated scene file: ``(kind, bytes)``.

    Kinds: byte flips, truncation, deep nesting, alias bombs, huge numbers, wrong types,
    unknown keys, non-UTF-8, duplicate keys, tabs, YAML tags, multi-documents, long lists
    (up to 400 items; 5,000 with ``big``, which take seconds to load).
    """
    lines = base.splitlines(keepends=True)
    data = base.encode()
    kind = rng.choice(['flip', 'flip', 'truncate', 'nesting', 'bomb', 'number', 'wrong_type',
                       'wrong_type', 'unknown_key', 'non_utf8', 'duplicate', 'tab', 'tag',
                       'documents', 'many_items', 'delete_line', 'swap_lines', 'control'])
    value_lines = [i for i, line in enumerate(lines) if ': ' in line and not
                   line.rstrip().endswith(':')]
    if kind == 'flip':
        b = bytearray(data)
        for _ in range(rng.choice([1, 1, 2, 3, 8, 50])):
            b[rng.randrange(len(b))] ^= 1 << rng.randrange(8) if rng.random() < 0.7 \
                else rng.randrange(1, 256)
        return kind, bytes(b)
    if kind == 'truncate':
        return kind, data[:rng.randrange(len(data) + 1)]
    if kind == 'nesting':
        depth = rng.choice([10, 31, 33, 100, 1000, 5000, 20000])
        i = rng.choice(value_lines)
        key = lines[i].split(': ')[0]
        opener, closer = rng.choice([('[', ']'), ('{a: ', '}'), ('- ', '')])
        if opener == '- ':   # block sequences nested by indentation
            nested = ''.join('\n' + ' ' * (len(key) + 2 + 2 * k) + '- ' for k in range(
                min(depth, 300))) + '1'
        else:
            nested = opener * depth + '1' + closer * depth
        lines[i] = f'{key}: {nested}\n'
        return kind, ''.join(lines).encode()
    if kind == 'bomb':
        levels = rng.choice([3, 5, 6, 7, 9, 10, 12])
        anchors, ref = _bomb(levels, rng.choice([2, 10, 20]))
        i = rng.choice(value_lines)
        key = lines[i].split(': ')[0]
        lines[i] = f'{key}: {ref}\n'
        return kind, (anchors + ''.join(lines)).encode()
    if kind in ('number', 'wrong_type', 'control'):
        i = rng.choice(value_lines)
        key = lines[i].split(': ')[0]
        if kind == 'number':
            value = rng.choice(['1e308', '-1e308', '1e309', '5e-324', '-5e-324', '.nan', '-.inf',
                                str(10**400), '-' + str(10**30), '0', '-0.0', '2.2e-308 mm',
                                '1e300 kg', '1e-300 Hz', '1e15', '4294967297', '1e-9 s',
                                '1e-12 s', '1e4 s', '1e6'])
        elif kind == 'wrong_type':
            value = rng.choice(_WRONG_TYPED)
        else:
            value = rng.choice(['"\\x00"', '"\\u0007"', '"\\u202e"', '"' + 'x' * 100_000 + '"',
                                '"\\U0001F4A9"'])
        lines[i] = f'{key}: {value}\n'
        return kind, ''.join(lines).encode()
    if kind == 'unknown_key':
        i = rng.randrange(len(lines) + 1)
        indent = lines[i - 1][:len(lines[i - 1]) - len(lines[i - 1].lstrip())] if i else ''
        name = rng.choice(['bogus', '__class__', 'n_modes', 'impactors', '<<', '?', '""',
                           '0', 'structure', 'é', '"a.b"'])
        lines.insert(i, f'{indent}{name}: {rng.choice(_WRONG_TYPED[:12])}\n')
        return kind, ''.join(lines).encode()
    if kind == 'non_utf8':
        b = bytearray(data)
        junk = rng.choice([b'\xff', b'\xfe\xff', b'\xc0\x80', b'\xed\xa0\x80', b'\x80\x80',
                           b'\xf8\x88\x80\x80\x80', bytes(rng.randrange(256) for _ in range(300))])
        at = rng.randrange(len(b) + 1)
        b[at:at] = junk
        if rng.random() < 0.2:
            return 'utf16', base.encode('utf-16')
        return kind, bytes(b)
    if kind == 'duplicate':
        i = rng.choice(value_lines)
        lines.insert(i + 1, lines[i])
        return kind, ''.join(lines).encode()
    if kind == 'tab':
        i = rng.randrange(len(lines))
        lines[i] = '\t' + lines[i]
        return kind, ''.join(lines).encode()
    if kind == 'tag':
        i = rng.choice(value_lines)
        key, value = lines[i].rstrip('\n').split(': ', 1)
        tag = rng.choice(['!!python/object/apply:os.system', '!!python/name:os.system',
                          '!!str', '!!int', '!!float', '!!map', '!!set', '!!omap', '!custom',
                          '!!python/object/new:type'])
        lines[i] = f'{key}: {tag} {value}\n'
        return f'{kind}:{tag}', ''.join(lines).encode()
    if kind == 'documents':
        return kind, rng.choice([data + b'---\n' + data, b'--- 1\n', b'', b'# only a comment\n',
                                 b'...\n', b'[1, 2]\n', b'just text\n', b'~\n',
                                 b'%YAML 1.1\n---\n' + data, b'%YAML 9.9\n---\n' + data])
    if kind == 'many_items':
        n = rng.choice([20, 200, 1000, 5000] if big else [20, 100, 400])
        section = rng.choice(['sensors', 'impactors', 'forcing'])
        item = {'sensors': '  - {name: s%d, node: 0, dof: uy}\n',
                'impactors': '  - {name: d%d, kind: sdof, node: 0, dof: uy, mass_ratio: 0.001, '
                             'cor: 0.5, clearance: 4.8 mm}\n',
                'forcing': '  - {node: 0, dof: uy, amplitude: 1 N, frequency_ratio: 1.0}\n'}[
                    section]
        at = next(i for i, line in enumerate(lines) if line.startswith(section + ':'))
        lines[at + 1:at + 1] = [item.replace('%d', str(k)) if '%d' in item else item
                                for k in range(n)]
        return f'{kind}:{section}', ''.join(lines).encode()
    if kind == 'delete_line':
        del lines[rng.randrange(len(lines))]
        return kind, ''.join(lines).encode()
    # swap_lines
    i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
    lines[i], lines[j] = lines[j], lines[i]
    return kind, ''.join(lines).encode()


# --- MCAP logs --------------------------------------------------------------------------------

class _Counting:
    def __init__(self, f):
        self.f, self.position = f, 0

    def read(self, n=-1):
        data = self.f.read(n)
        self.position += len(data)
        return data


def chunk_table(path):
    """The chunks of a finished MCAP file, in file order.

    Returns
    -------
    list of dict
        ``start``, ``end`` (byte offsets, end exclusive), ``records`` (offset of the chunk's
        first inner record), ``messages`` (count), ``channels`` (Channel or Schema records
        inside it: bool).
    """
    from mcap.records import Channel, Chunk, Message, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk
    table = []
    with open(path, 'rb') as f:
        stream = _Counting(f)
        records = iter(StreamReader(stream, emit_chunks=True).records)
        start = stream.position
        for record in records:
            end = stream.position
            if isinstance(record, Chunk):
                inner = breakup_chunk(record, validate_crc=True)
                table.append({
                    'start': start, 'end': end,
                    'records': start + 1 + 8 + 8 + 8 + 8 + 4 + 4 + len(record.compression) + 8,
                    'messages': sum(isinstance(r, Message) for r in inner),
                    'channels': any(isinstance(r, (Channel, Schema)) for r in inner)})
            start = end
    return table


def corrupt_log(rng, blob, chunks):
    """One corrupted copy of an MCAP file: ``(kind, bytes, first changed byte offset)``.

    ``chunks`` is :func:`chunk_table` of ``blob``. Everything before the returned offset is
    the original's bytes (an intact prefix that recovery must keep).
    """
    n = len(blob)
    kind = rng.choice(['flip', 'flip', 'flip_in_chunk', 'flip_in_chunk', 'truncate',
                       'truncate', 'zero_range', 'insert', 'delete', 'duplicate',
                       'length_absurd', 'swap_chunks', 'append', 'strip_tail', 'profile',
                       'garbage', 'time_absurd'])
    b = bytearray(blob)
    if kind == 'flip':
        offsets = sorted(rng.randrange(n) for _ in range(rng.choice([1, 2, 4, 16, 64])))
        for at in offsets:
            b[at] ^= rng.randrange(1, 256)
        return kind, bytes(b), offsets[0]
    if kind == 'flip_in_chunk':   # inside one chunk's records: its framing stays intact
        c = rng.choice(chunks)
        at = rng.randrange(c['records'], c['end'])
        b[at] ^= rng.randrange(1, 256)
        return f"flip_in_chunk:{chunks.index(c)}", bytes(b), at
    if kind == 'truncate':
        at = rng.choice([rng.randrange(n), rng.choice(chunks)['end'] + rng.choice([-1, 0, 1]),
                         rng.randrange(8, 40)])
        return kind, blob[:at], at
    if kind == 'zero_range':
        at = rng.randrange(n)
        length = rng.choice([1, 8, 100, 4096])
        b[at:at + length] = bytes(len(b[at:at + length]))
        return kind, bytes(b), at
    if kind == 'insert':
        at = rng.randrange(n)
        b[at:at] = bytes(rng.randrange(256) for _ in range(rng.choice([1, 9, 100])))
        return kind, bytes(b), at
    if kind == 'delete':
        at = rng.randrange(n)
        del b[at:at + rng.choice([1, 9, 100, 5000])]
        return kind, bytes(b), at
    if kind == 'duplicate':
        c = rng.choice(chunks)
        b[c['end']:c['end']] = blob[c['start']:c['end']]
        return kind, bytes(b), c['end']
    if kind == 'length_absurd':   # a record's length field: 2^63 - 1, 2^40, 0 or off by one
        c = rng.choice(chunks)
        at = rng.choice([c['start'], c['records']])
        old = struct.unpack_from('<Q', b, at + 1)[0]
        value = rng.choice([2**63 - 1, 2**64 - 1, 2**40, 0, old + 1, max(old - 1, 0)])
        struct.pack_into('<Q', b, at + 1, value)
        return kind, bytes(b), at + 1
    if kind == 'swap_chunks' and len(chunks) >= 2:
        i, j = sorted(rng.sample(range(len(chunks)), 2))
        ci, cj = chunks[i], chunks[j]
        out = (blob[:ci['start']] + blob[cj['start']:cj['end']] + blob[ci['end']:cj['start']]
               + blob[ci['start']:ci['end']] + blob[cj['end']:])
        return kind, out, ci['start']
    if kind == 'append':
        return kind, blob + bytes(rng.randrange(256) for _ in range(rng.choice([1, 100]))), n
    if kind == 'strip_tail':
        return kind, blob[:-rng.choice([1, 8, 9, 100])], n - 100
    if kind == 'profile':   # the header's profile string 'ros2' -> something else
        at = blob.find(b'ros2')
        b[at:at + 4] = rng.choice([b'ros1', b'\x00\x00\x00\x00', b'ROS2', b'\xff\xfe\xfd\xfc'])
        return kind, bytes(b), at
    if kind == 'time_absurd':   # a message's log time in a chunk: 2^63 - 1 (CRC broken too)
        c = rng.choice(chunks)
        at = blob.find(b'\x05', c['records'], c['end'])   # a Message record's opcode
        if at < 0:
            at = c['records']
        struct.pack_into('<Q', b, min(at + 1 + 8 + 2 + 4, n - 8), 2**63 - 1)
        return kind, bytes(b), at
    # garbage: not an MCAP file at all, or only its magic
    return 'garbage', rng.choice([b'', blob[:8], blob[:9], bytes(rng.randrange(256)
                                                                for _ in range(1000)),
                                  b'\x89MCAP0\r\n' * 3]), 0
