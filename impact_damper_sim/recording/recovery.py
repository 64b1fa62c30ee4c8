"""Recover an MCAP file cut off by a crash (no summary, no footer) into a finished one.

The input is read front to back, record by record (each framed by its opcode and length and
parsed by mcap's record classes; chunks whole, each checked against its CRC and size). A
chunk whose contents are broken (CRC or size mismatch) while its framing is intact is
skipped, and reading goes on with the records after it (the message indexes that follow it
tell how many messages it held). A record that is itself broken (a damaged opcode or
length, a footer before the end) makes the reader look for the next intact chunk (its
length fields consistent and its CRC right) and go on from there; reading stops at a broken
record with no intact chunk after it (a crash file's cut-off end). The writer
(:class:`.Rosbag2McapWriter`) writes each schema and channel record outside the chunks
when its topic is registered, so in its files one damaged chunk loses that chunk's messages
only. A channel whose only record was in a skipped chunk (older files, other writers) is
taken from the summary section (through the footer, or the summary offsets) or, failing
that, from a later copy of the record; in a crash file with no summary its messages cannot
be attributed and are counted as skipped. Everything read is copied: schemas, channels
(with their QoS and type-hash metadata), messages (log and publish times and sequence kept),
metadata records and attachments. A crashed recording therefore keeps everything up to its
last complete chunk.
The output is written in rosbag2's layout (:class:`.Rosbag2McapWriter`) with a fresh
``rosbag2`` record counting what was recovered (a stale one in the input is dropped).

Command: ``study recover CRASHED.mcap OUT.mcap [--overwrite] [--json]``.
"""
from __future__ import annotations

import dataclasses
import errno
import io
import os
import struct

from .log_file import log_error
from .rosbag2_mcap import Rosbag2McapWriter

MAGIC = b'\x89MCAP0\r\n'


class RecoveryError(ValueError):
    """The input is not a ROS 2 MCAP file that can be recovered (message says why)."""


@dataclasses.dataclass
class RecoveryReport:
    """What :func:`recover` found and wrote.

    Attributes
    ----------
    source, destination : str
        Input and output paths.
    messages : int
        Messages written to the output (messages).
    topics : dict of str to int
        Messages per topic (messages), channels without messages included.
    metadata : list of str
        Names of the metadata records copied (``rosbag2`` is always rewritten).
    attachments : int
        Attachments copied.
    complete : bool
        True if the input had its footer (it was not cut off).
    bytes_used, bytes_total : int
        Input bytes up to the end of the last good record, and the input size (bytes).
    stop_reason : str or None
        Why reading stopped before the footer (None when complete).
    skipped_messages : int
        Messages of unknown channels (not written): their channel records were in a corrupt
        chunk or past the end of the readable data, with no copy elsewhere in the file.
    skipped_channels : int
        Distinct unknown channel ids of those messages.
    restored_channels : dict of str to str
        Topics whose channel record was not read before their first message (it was in a
        corrupt chunk), to where it was taken from instead: ``'summary section'`` or
        ``'later record'``.
    corrupt_chunks : int
        Chunks skipped because their contents were broken (chunks).
    corrupt_chunk_numbers : list of int
        Their places among the file's chunks (0 is the first chunk).
    corrupt_chunk_messages : int
        Messages those chunks held, from their message indexes (messages; 0 when the
        indexes are missing too).
    damaged_ranges : list of [int, int]
        Byte ranges ``[start, end)`` skipped over because a record there was broken
        (reading went on at the next intact chunk, at ``end``).
    start_ns, end_ns : int or None
        Earliest and latest recovered log time (ns since the epoch).
    """

    source: str
    destination: str
    messages: int = 0
    topics: dict = dataclasses.field(default_factory=dict)
    metadata: list = dataclasses.field(default_factory=list)
    attachments: int = 0
    complete: bool = False
    bytes_used: int = 0
    bytes_total: int = 0
    stop_reason: str | None = None
    skipped_messages: int = 0
    skipped_channels: int = 0
    restored_channels: dict = dataclasses.field(default_factory=dict)
    corrupt_chunks: int = 0
    corrupt_chunk_numbers: list = dataclasses.field(default_factory=list)
    corrupt_chunk_messages: int = 0
    damaged_ranges: list = dataclasses.field(default_factory=list)
    start_ns: int | None = None
    end_ns: int | None = None


class _StrictReader:
    """File wrapper for StreamReader: a short read raises (mcap would return short data)."""

    def __init__(self, f):
        self._f = f
        self.position = 0

    def read(self, n=-1):
        from mcap.exceptions import EndOfFile
        data = self._f.read(n)
        if n is not None and n >= 0 and len(data) < n:
            raise EndOfFile(f'file ends {n - len(data)} bytes into a record')
        self.position += len(data)
        return data


def _chunk_records(chunk):
    """Return the records of a chunk, checked against its CRC and size; raise if broken."""
    from mcap.stream_reader import breakup_chunk, get_chunk_data_stream
    _, length = get_chunk_data_stream(chunk)
    if length != chunk.uncompressed_size:
        raise ValueError(f'chunk holds {length} bytes, its header says {chunk.uncompressed_size}')
    return breakup_chunk(chunk, validate_crc=True)


class _Broken(Exception):
    """The bytes at a place are not a whole, well-formed record (message says why)."""


def _parsers():
    """Record parsers by opcode: ``parse(stream, length)`` (mcap's record classes)."""
    from mcap import records as r
    from mcap.opcode import Opcode
    table = {getattr(Opcode, name): (lambda stream, length, cls=cls: cls.read(stream))
             for name, cls in [('ATTACHMENT', r.Attachment), ('ATTACHMENT_INDEX',
                               r.AttachmentIndex), ('CHANNEL', r.Channel), ('CHUNK', r.Chunk),
                               ('CHUNK_INDEX', r.ChunkIndex), ('DATA_END', r.DataEnd),
                               ('FOOTER', r.Footer), ('HEADER', r.Header),
                               ('MESSAGE_INDEX', r.MessageIndex), ('METADATA', r.Metadata),
                               ('METADATA_INDEX', r.MetadataIndex), ('SCHEMA', r.Schema),
                               ('STATISTICS', r.Statistics),
                               ('SUMMARY_OFFSET', r.SummaryOffset)]}
    table[Opcode.MESSAGE] = r.Message.read
    return table


def _record_at(f, pos, size, parsers):
    """Read the record at byte ``pos``; raise :class:`_Broken` unless it is whole and parses.

    Returns the record, the end of the record by its length field, and the end of what its
    fields took (the same unless the length field is wrong, or a newer writer added fields).
    An unknown opcode counts as broken: ROS 2 writers write none, and skipping an unknown
    record by a damaged length could jump over good chunks.
    """
    from mcap.data_stream import ReadDataStream
    f.seek(pos)
    head = f.read(9)
    if len(head) < 9:
        raise _Broken(f'the file ends {9 - len(head)} bytes into a record header')
    opcode, length = struct.unpack('<BQ', head)
    parse = parsers.get(opcode)
    if parse is None:
        raise _Broken(f'unknown record opcode {opcode:#04x}')
    if length > size - pos - 9:
        raise _Broken(f'a record of {length} bytes runs {length - (size - pos - 9)} bytes '
                      'past the end of the file')
    stream = ReadDataStream(_StrictReader(io.BytesIO(f.read(length))))
    try:
        record = parse(stream, length)
    except Exception as exc:   # any parse failure: fields that do not fit the record
        raise _Broken(f'a broken record (opcode {opcode:#04x}): {type(exc).__name__}: '
                      f'{exc}') from None
    return record, pos + 9 + length, pos + 9 + stream.count


#: Block (bytes) read at a time while looking for the next intact chunk.
_SCAN_BLOCK = 1 << 20


def _next_chunk(f, start, size, parsers):
    """Offset of the first intact chunk at or after byte ``start``, or None.

    A candidate is a chunk opcode whose length equals its fields' sizes (a 64-bit equation
    that random bytes meet with odds of 2**-64) and whose records check against its CRC.
    """
    at = start
    while at < size:
        f.seek(at)
        data = f.read(_SCAN_BLOCK)
        i = data.find(b'\x06')
        while i >= 0:
            if _intact_chunk_at(f, at + i, size, parsers):
                return at + i
            i = data.find(b'\x06', i + 1)
        at += len(data)
    return None


def _intact_chunk_at(f, pos, size, parsers):
    f.seek(pos)
    # opcode, length, start and end times, uncompressed size, CRC, compression length
    head = f.read(41 + 4 + 8)
    if len(head) < 41:
        return False
    length, compression_length = struct.unpack_from('<Q', head, 1)[0], \
        struct.unpack_from('<I', head, 37)[0]
    if compression_length > 4 or len(head) < 49 + compression_length \
            or length > size - pos - 9:
        return False
    records_length = struct.unpack_from('<Q', head, 41 + compression_length)[0]
    if length != 40 + compression_length + records_length:
        return False
    try:
        _chunk_records(_record_at(f, pos, size, parsers)[0])
    except Exception:   # _Broken, or a CRC / size mismatch
        return False
    return True


def _check_source(path):
    from ..scene.loading import file_kind
    try:
        kind = file_kind(path)   # before opening: a FIFO would block, /dev/zero never end
        if kind:
            raise RecoveryError(f'{path}: {kind}, not an MCAP file (not a regular file)')
        size = os.path.getsize(path)
        with open(path, 'rb') as f:
            head = f.read(len(MAGIC))
    except FileNotFoundError:
        raise RecoveryError(f'{path}: no such file') from None
    except OSError as exc:
        raise RecoveryError(f'{path}: cannot read it: {exc.strerror or exc}') from None
    if size == 0:
        raise RecoveryError(f'{path}: the file is empty (0 bytes), nothing to recover')
    if head != MAGIC[:len(head)] or len(head) < len(MAGIC):
        what = 'is too short for' if head == MAGIC[:len(head)] else 'does not start with'
        raise RecoveryError(f'{path}: not an MCAP file (it {what} the MCAP magic bytes)')
    return size


def _summary_definitions(f, size):
    """Schemas and channels of the summary section, found through the footer.

    Used for channels whose only records were in a chunk that is now corrupt (files of
    other writers, and ours before the definitions were also written outside chunks: the
    first chunk held them all). Each place the
    footer points at is read on its own (the summary start, then every group start of the
    summary offsets), up to its first broken record, keeping what was read before it.

    Parameters
    ----------
    f : file
        The input, open for binary reading (seekable).
    size : int
        Its size (bytes).

    Returns
    -------
    schemas, channels : dict of int to mcap.records.Schema, dict of int to mcap.records.Channel
        Empty when the file has no readable footer or summary (a crash file).
    """
    from mcap.records import Channel, Footer, Schema, SummaryOffset
    from mcap.stream_reader import StreamReader

    footer_size = 1 + 8 + 8 + 8 + 4   # opcode, length, summary start, offsets start, CRC
    schemas, channels = {}, {}

    def records_at(offset):
        f.seek(offset)
        return StreamReader(_StrictReader(f), skip_magic=True,
                            record_size_limit=size).records

    def collect(offset, kinds, stop):
        found = []
        try:
            for record in records_at(offset):
                if isinstance(record, stop):
                    break
                if isinstance(record, kinds):
                    found.append(record)
        except Exception:   # a broken record ends this place; keep what came before it
            pass
        return found

    try:
        footer = next(iter(records_at(size - footer_size - len(MAGIC))))
    except Exception:   # no footer: a crash file (or a broken end)
        return schemas, channels
    if not isinstance(footer, Footer):
        return schemas, channels
    starts = [footer.summary_start] if 0 < footer.summary_start < size else []
    if 0 < footer.summary_offset_start < size:
        starts += [o.group_start for o in collect(footer.summary_offset_start, SummaryOffset,
                                                  Footer) if 0 < o.group_start < size]
    for offset in starts:
        for record in collect(offset, (Schema, Channel), (SummaryOffset, Footer)):
            (schemas if isinstance(record, Schema) else channels).setdefault(record.id, record)
    return schemas, channels


def recover(source, destination, *, overwrite=False):
    """Copy the readable part of a (crashed) MCAP file into a finished rosbag2-layout file.

    Schemas and channels come from where they are first read in the file (our writer puts
    a copy of each outside the chunks, before its first message); for one whose only record
    was in a corrupt chunk (other writers put them all in the first chunk), from the summary
    section or, failing that, from a later copy of the record (then the input is read
    twice). What stays unattributed is counted in ``skipped_messages``. A broken record
    (damaged framing) is skipped up to the next intact chunk (``damaged_ranges``).

    Parameters
    ----------
    source : str or os.PathLike
        The cut-off MCAP file (a complete file works too).
    destination : str or os.PathLike
        Output file.
    overwrite : bool, optional
        Replace an existing output file.

    Returns
    -------
    RecoveryReport

    Raises
    ------
    RecoveryError
        If the input is missing, empty, not MCAP, has no complete header, or is not a ROS 2
        (profile ``ros2``) file, or if input and output are the same file.
    FileExistsError
        If the output exists and ``overwrite`` is false.
    """
    source, destination = os.fspath(source), os.fspath(destination)
    size = _check_source(source)
    if os.path.exists(destination) and os.path.samefile(source, destination):
        raise RecoveryError(f'{destination}: the output must not be the input file')
    with open(source, 'rb') as f:
        fallback = _summary_definitions(f, size)
    report, late = _copy(source, destination, size, overwrite, fallback)
    if late:   # definitions found only after their messages: a second pass with them
        schemas, channels = fallback
        report, _ = _copy(source, destination, size, True,
                          ({**late[0], **schemas}, {**late[1], **channels}))
        for topic in report.restored_channels:
            if not any(c.topic == topic for c in channels.values()):
                report.restored_channels[topic] = 'later record'
    return report


def _copy(source, destination, size, overwrite, fallback):
    """One pass of :func:`recover`: copy ``source`` into ``destination``.

    ``fallback`` is ``(schemas, channels)`` by id, for channels whose record is not read
    before their first message. Returns the report and, when messages were skipped whose
    channel record turned up later in the file, ``(schemas, channels)`` found in the file
    (else None).
    """
    from mcap.records import (
        Attachment,
        Channel,
        Chunk,
        Footer,
        Header,
        Message,
        MessageIndex,
        Metadata,
        Schema,
    )

    report = RecoveryReport(source, destination, bytes_total=size)
    fallback_schemas, fallback_channels = fallback
    skipped_ids = set()
    parsers = _parsers()
    with open(source, 'rb') as f:
        try:
            header, _, header_end = _record_at(f, len(MAGIC), size, parsers)
        except _Broken as exc:   # any parse failure of the first record means no header
            raise RecoveryError(f'{source}: no complete MCAP header record ({exc})') from None
        if not isinstance(header, Header):
            raise RecoveryError(f'{source}: the first record is a {type(header).__name__}, '
                                'not an MCAP header')
        if header.profile != 'ros2':
            raise RecoveryError(f"{source}: not a ROS 2 MCAP file (profile {header.profile!r},"
                                " expected 'ros2')")
        report.bytes_used = header_end
        schemas, in_channels, out_channels = {}, {}, {}
        writer = Rosbag2McapWriter(destination, overwrite=overwrite, fsync_period=None)

        def add_channel(record, restored):
            in_channels[record.id] = record
            schema = schemas.get(record.schema_id) or fallback_schemas.get(record.schema_id)
            out_channels[record.id] = _copy_channel(writer, record, schema)
            report.topics.setdefault(record.topic, 0)
            if restored:
                report.restored_channels[record.topic] = 'summary section'

        def copy(record):
            if isinstance(record, Schema):
                schemas.setdefault(record.id, record)
            elif isinstance(record, Channel):
                if record.id not in in_channels:
                    add_channel(record, False)
            elif isinstance(record, Message):
                channel = out_channels.get(record.channel_id)
                if channel is None and record.channel_id in fallback_channels:
                    add_channel(fallback_channels[record.channel_id], True)
                    channel = out_channels[record.channel_id]
                if channel is None:
                    report.skipped_messages += 1
                    skipped_ids.add(record.channel_id)
                    return
                writer._add_message(channel, record.data, record.log_time, record.publish_time,
                                    record.sequence)
                report.topics[channel.topic] += 1
                report.messages += 1
                if report.start_ns is None or record.log_time < report.start_ns:
                    report.start_ns = record.log_time
                if report.end_ns is None or record.log_time > report.end_ns:
                    report.end_ns = record.log_time
            elif isinstance(record, Metadata) and record.name != 'rosbag2':
                writer.add_metadata(record.name, record.metadata)
                report.metadata.append(record.name)
            elif isinstance(record, Attachment):
                writer._mcap.add_attachment(record.create_time, record.log_time, record.name,
                                            record.media_type, record.data)
                report.attachments += 1

        after_corrupt_chunk, n_chunks = False, 0
        pos = scan_from = header_end   # scan_from: where unexplained bytes would begin
        try:
            while True:
                if pos >= size:
                    report.stop_reason = ('the file ends after a complete record, without a '
                                          'footer (the open chunk was never written)')
                    break
                try:
                    record, end, fields_end = _record_at(f, pos, size, parsers)
                    if isinstance(record, Footer) and end != size - len(MAGIC):
                        raise _Broken('a footer record before the end of the file')
                except _Broken as exc:
                    resume = _next_chunk(f, scan_from, size, parsers)
                    if resume is None:
                        report.stop_reason = (f'incomplete or broken record after byte {pos}: '
                                              f'{exc}')
                        break
                    report.damaged_ranges.append([scan_from, resume])
                    pos = scan_from = resume
                    after_corrupt_chunk = False
                    continue
                pos, scan_from = end, fields_end
                if isinstance(record, MessageIndex):
                    if after_corrupt_chunk:   # the skipped chunk's messages, counted
                        report.corrupt_chunk_messages += len(record.records)
                    report.bytes_used = pos
                    continue
                inner = [record]
                if isinstance(record, Chunk):
                    try:
                        inner = _chunk_records(record)
                    except Exception:   # its framing held: skip it, keep what follows
                        report.corrupt_chunk_numbers.append(n_chunks)
                        n_chunks += 1
                        report.corrupt_chunks += 1
                        after_corrupt_chunk = True
                        report.bytes_used = scan_from = pos
                        continue
                    n_chunks += 1
                    pos = fields_end   # intact (CRC): it ends where its records end
                after_corrupt_chunk = False
                for item in inner:
                    copy(item)
                report.bytes_used = pos
                if isinstance(record, Footer):
                    report.complete = True
                    break
        finally:
            writer.close()
    if not writer.finished:
        raise _write_failed(writer)
    report.skipped_channels = len(skipped_ids)
    if skipped_ids & in_channels.keys():
        return report, (schemas, {i: in_channels[i] for i in skipped_ids & in_channels.keys()})
    return report, None


def _copy_channel(writer, channel, schema):
    """Register ``channel`` (and its ``schema``, or None) in the output; return the output
    channel."""
    import yaml
    metadata = dict(channel.metadata)
    try:
        qos = yaml.safe_load(metadata.get('offered_qos_profiles', '')) or []
    except Exception:   # damaged text: PyYAML raises ValueError etc. too ('!!int x')
        qos = []
    out = writer._register(
        channel.topic, schema.name if schema else '', schema.encoding if schema else '',
        schema.data if schema else b'', channel.message_encoding,
        qos if isinstance(qos, list) else [], metadata.get('topic_type_hash', ''), metadata)
    if out is None:
        raise _write_failed(writer)
    return out


def _write_failed(writer):
    """The one-line ``OSError`` for an output that is not a finished file."""
    error = writer.error
    code = getattr(error, 'errno', None) or errno.EIO
    reason = getattr(error, 'strerror', None) or str(error)
    if writer.path in reason:   # the writer's own one-line text names the file already
        return log_error(code, reason, writer.path)
    return log_error(code, f'{writer.path}: writing failed: {reason}', writer.path)
