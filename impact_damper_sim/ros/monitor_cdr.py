"""PointCloud2 batches read from their CDR bytes, for the monitor's raw subscriptions.

rclpy turns each received PointCloud2 into Python objects (a Header, a Time, one PointField
per field): measured with ten synthetic hpotp machines (2,000 batch messages/s), that took
about 110 us a message, most of the monitor's CPU. The monitor subscribes to its batch topics
with ``raw=True`` instead, queues the bytes as they come, and its report thread reads them
here: a few ``struct`` reads for the header and the layout (the layout's bytes are the same
message after message, so a reader keeps what it read of each layout), and the rows as one
NumPy view. The result quacks like a decoded message for
:func:`impact_damper_sim.recording.batches.rows_of` and ``sample_times_ns``.

The bytes are XCDR1 little-endian as rclpy gives them (a 4-byte encapsulation header, then
the fields aligned to their size counted from after it).
"""
from __future__ import annotations

import struct

_U32 = struct.Struct('<I')
_STAMP = struct.Struct('<iI')
_LITTLE_ENDIAN_CDR = (b'\x00\x01', b'\x00\x03')   # CDR_LE, PL_CDR_LE


class _Stamp:
    __slots__ = ('sec', 'nanosec')

    def __init__(self, sec, nanosec):
        self.sec, self.nanosec = sec, nanosec


class _Header:
    __slots__ = ('stamp', 'frame_id')

    def __init__(self, stamp, frame_id):
        self.stamp, self.frame_id = stamp, frame_id


class _Field:
    __slots__ = ('name', 'offset', 'datatype', 'count')

    def __init__(self, name, offset, datatype, count):
        self.name, self.offset, self.datatype, self.count = name, offset, datatype, count


class Cloud:
    """A PointCloud2 read from CDR: ``header``, ``height``, ``width``, ``fields``,
    ``is_bigendian``, ``point_step``, ``row_step``, ``data`` (a memoryview of the bytes)."""

    __slots__ = ('header', 'height', 'width', 'fields', 'is_bigendian', 'point_step',
                 'row_step', 'data')


def _string(buf, at):
    """A CDR string at ``at`` (aligned): (text, offset after it)."""
    n = _U32.unpack_from(buf, at)[0]
    end = at + 4 + n
    if n < 1 or end > len(buf):
        raise ValueError('PointCloud2: a string runs past the end of the message')
    return bytes(buf[at + 4:end - 1]).decode('utf-8', 'replace'), end


def _align(at, n):
    # offsets count from the 4-byte encapsulation header
    return at + (-(at - 4) % n)


def _layout(buf, at):
    """Fields, is_bigendian, point_step, row_step's offset: from ``at`` (the field count)."""
    count = _U32.unpack_from(buf, at)[0]
    if count > 64:
        raise ValueError(f'PointCloud2: {count} fields')
    at += 4
    fields = []
    for _ in range(count):
        name, at = _string(buf, at)
        at = _align(at, 4)
        offset = _U32.unpack_from(buf, at)[0]
        datatype = buf[at + 4]
        at = _align(at + 5, 4)
        fields.append(_Field(name, offset, datatype, _U32.unpack_from(buf, at)[0]))
        at += 4
    bigendian = bool(buf[at])
    at = _align(at + 1, 4)
    return tuple(fields), bigendian, _U32.unpack_from(buf, at)[0], at + 4


def rows_in(data):
    """Rows a PointCloud2's CDR bytes claim (``height * width``; cheap: for queue limits).

    Returns 1 for bytes too short to say.
    """
    try:
        n = _U32.unpack_from(data, 12)[0]
        at = _align(16 + n, 4)
        height, width = struct.unpack_from('<II', data, at)
        return height * width
    except struct.error:
        return 1


def read_cloud(data, layouts=None):
    """Read one PointCloud2 from its CDR bytes.

    Parameters
    ----------
    data : bytes
        The serialized message, as a ``raw=True`` subscription receives it.
    layouts : dict, optional
        The caller's cache of layouts read before (the bytes of a layout to its fields,
        endianness, point step and length), filled here; None reads the layout every time.

    Returns
    -------
    Cloud

    Raises
    ------
    ValueError
        Not little-endian CDR, or the bytes end before the message does.
    """
    buf = memoryview(data)
    if bytes(buf[:2]) not in _LITTLE_ENDIAN_CDR:
        raise ValueError('PointCloud2: not little-endian CDR')
    try:
        sec, nanosec = _STAMP.unpack_from(buf, 4)
        frame, at = _string(buf, 12)
        at = _align(at, 4)
        height, width = struct.unpack_from('<II', buf, at)
        at += 8
        # the layout ends at row_step: find it once per layout, by its bytes
        known = None
        for key, value in (layouts or {}).items():
            if buf[at:at + len(key)] == key:
                known = value
                break
        if known is None:
            fields, bigendian, step, end = _layout(buf, at)
            known = (fields, bigendian, step, end - at)
            if layouts is not None and len(layouts) < 64:
                layouts[bytes(buf[at:end])] = known
        fields, bigendian, step, length = known
        at += length
        row_step, size = struct.unpack_from('<II', buf, at)
        at += 8
        if at + size > len(buf):
            raise ValueError(f'PointCloud2: data claims {size} bytes, '
                             f'{len(buf) - at} are left')
    except struct.error as error:
        raise ValueError(f'PointCloud2: the bytes end early ({error})') from None
    cloud = Cloud()
    cloud.header = _Header(_Stamp(sec, nanosec), frame)
    cloud.height, cloud.width, cloud.fields = height, width, fields
    cloud.is_bigendian, cloud.point_step, cloud.row_step = bigendian, step, row_step
    cloud.data = buf[at:at + size]
    return cloud


__all__ = ['Cloud', 'read_cloud', 'rows_in']
