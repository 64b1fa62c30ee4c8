"""``study recover CRASHED.mcap OUT.mcap [--overwrite] [--json]`` (see :mod:`.recovery`).

Exit status 0 with the counts on stdout; 1 with one line on stderr saying why when nothing
could be kept from an input that was cut off or damaged (an intact log with no messages is
not a failure); 2 with one message on stderr (no traceback) for a missing, empty, garbage or
non-ROS 2 input, an existing OUT without ``--overwrite``, or an OUT that cannot be written
(a writer holding it included). Importing this module is cheap (mcap is imported when the
command runs).
"""
from __future__ import annotations

import json
import sys

from .._exit_status import EXIT_USAGE

EXIT_NOTHING_KEPT = 1
#: where :func:`.recovery.recover` took a lost channel definition from, in words
_SOURCES = {'summary section': "the file's summary section",
            'later record': 'later copies of their records in the file'}


def add_recover_parser(sub):
    """Add the ``recover`` subcommand to an argparse sub-parser collection.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``study`` command's sub-parsers.
    """
    p = sub.add_parser(
        'recover', help='make a finished MCAP from one cut off by a crash',
        description='Copy everything up to the last complete chunk of an MCAP recording cut '
                    'off by a crash (kill -9, power loss: no summary, no footer) into a valid, '
                    'finished MCAP in rosbag2 layout: schemas, channels with their QoS, '
                    'messages with their log and publish times, metadata records. Prints the '
                    'counts per topic. Exit status 1 (one line saying why) when it keeps no '
                    'message of a cut-off or damaged input.')
    p.add_argument('crashed', metavar='CRASHED.mcap', help='the cut-off MCAP file')
    p.add_argument('out', metavar='OUT.mcap', help='the recovered file to write')
    p.add_argument('--overwrite', action='store_true', help='replace OUT if it exists')
    p.add_argument('--json', action='store_true', help='print JSON instead of text')


def _error(message):
    print(f'study: error: {message}', file=sys.stderr)


def nothing_kept(report):
    """Say why a recovery kept no message, or return None (it kept some, or the input was an
    intact log holding none).

    Parameters
    ----------
    report : RecoveryReport
        What :func:`.recovery.recover` did.

    Returns
    -------
    str or None
        One line: the input, what was lost and where, and what the output holds.
    """
    damaged = report.corrupt_chunks or report.damaged_ranges or report.skipped_messages
    if report.messages or (report.complete and not damaged):
        return None
    why = []
    if report.corrupt_chunks:
        s = '' if report.corrupt_chunks == 1 else 's'
        why.append(f'its only data was in {report.corrupt_chunks} corrupt chunk{s} '
                   f'({report.corrupt_chunk_messages} messages by their indexes)')
    if report.damaged_ranges:
        skipped = sum(end - start for start, end in report.damaged_ranges)
        why.append(f'{skipped} bytes of damaged records were skipped')
    if report.skipped_messages:
        why.append(f'{report.skipped_messages} messages are on channels whose definitions '
                   'were lost')
    if not why:
        why.append(f'no complete chunk reached the file before it was cut off '
                   f'({report.stop_reason})')
    return (f'recovered no messages from {report.source}: {"; ".join(why)} '
            f'({report.destination} holds no messages)')


def run_recover(args):
    """Run ``study recover``.

    Parameters
    ----------
    args : argparse.Namespace
        ``crashed``, ``out``, ``overwrite``, ``json``.

    Returns
    -------
    int
        Exit status: 0 on success, 1 when no message was kept of a cut-off or damaged
        input, 2 for bad input or an output that exists or cannot be written.
    """
    from .log_file import FileLockedError, OneLineError
    from .recovery import RecoveryError, recover
    try:
        report = recover(args.crashed, args.out, overwrite=args.overwrite)
    except (RecoveryError, FileLockedError) as exc:
        _error(str(exc))
        return EXIT_USAGE
    except FileExistsError:
        _error(f'{args.out} exists; pass --overwrite to replace it')
        return EXIT_USAGE
    except OSError as exc:   # the writer's errors are one line naming the file already
        _error(str(exc) if isinstance(exc, OneLineError)
               else f'{exc.filename or args.out}: {exc.strerror or exc}')
        return EXIT_USAGE
    failure = nothing_kept(report)
    if args.json:
        print(json.dumps(report.__dict__, indent=2))
    if failure is not None:
        _error(failure)
        return EXIT_NOTHING_KEPT
    if args.json:
        return 0
    n_topics = len(report.topics)
    print(f'recovered {report.messages} messages on {n_topics} topic'
          f'{"" if n_topics == 1 else "s"} from {report.source} into {report.destination}')
    width = max((len(t) for t in report.topics), default=0)
    for topic, count in report.topics.items():
        print(f'  {topic:<{width}}  {count}')
    if report.start_ns is not None:
        print(f'log time span: {(report.end_ns - report.start_ns) / 1e9:.3f} s')
    if report.metadata:
        print(f'metadata records: {", ".join(report.metadata)}')
    if report.complete:
        print('the input was complete (it had its footer)')
    else:
        print(f'input: used {report.bytes_used} of {report.bytes_total} bytes; '
              f'{report.stop_reason}')
    if report.corrupt_chunks:
        s = '' if report.corrupt_chunks == 1 else 's'
        numbers = f'chunk{s} {", ".join(map(str, report.corrupt_chunk_numbers))}'
        print(f'skipped {report.corrupt_chunks} corrupt chunk{s} ({numbers}, counting from 0) '
              f'holding {report.corrupt_chunk_messages} messages; kept the chunks after them')
    for start, end in report.damaged_ranges:
        print(f'skipped bytes {start} to {end} (a broken record; reading went on at the next '
              'intact chunk)')
    for where in sorted(set(report.restored_channels.values())):
        topics = [t for t, w in report.restored_channels.items() if w == where]
        print(f'took {len(topics)} channel definition{"" if len(topics) == 1 else "s"} '
              f'from {_SOURCES.get(where, where)} (their records were in a corrupt chunk): '
              f'{", ".join(topics)}')
    if report.skipped_messages:
        what = (f'{report.skipped_messages} messages on {report.skipped_channels} unknown '
                f'channel{"" if report.skipped_channels == 1 else "s"}')
        if report.corrupt_chunks:
            print(f'skipped {what}: their channel definitions were lost with corrupt '
                  f'{numbers} and the file has no readable summary repeating them, so these '
                  'messages cannot be attributed to a topic')
        else:
            print(f'skipped {what}')
    return 0
