"""Merging a data set recorded part by part: ``study dataset --gather DIR [DIR ...] --out OUT``.

A data set split over machines without a shared file system is recorded part by part (one
grid slice or one sample seed per machine, each with ``study dataset SPEC --out PART``). Run
ids are digests of their inputs, so the parts' logs never collide; :func:`gather_datasets`
copies every finished log into one directory, checking it against its part's sha256 on the
way, and writes one manifest with :mod:`.dataset_manifest`'s writer, which a full-spec run
into the same directory then takes as finished. Separate from :mod:`.dataset` because it records
nothing: it only reads manifests and copies files.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re

from .dataset_manifest import (
    RESULT_COLUMNS,
    RUN_COLUMNS,
    file_sha256,
    manifest_rows,
    write_manifest,
)
from .dataset_spec import DatasetError

#: the manifest fields of a run that are not a grid or sample key
_RUN_FIELDS = frozenset((*(column for column, _ in RUN_COLUMNS), *RESULT_COLUMNS))
_OK_FIELDS = ('id', *RESULT_COLUMNS)
_ID = re.compile(r'[A-Za-z0-9_-][A-Za-z0-9_.-]*\Z')
_SHA256 = re.compile(r'[0-9a-f]{64}\Z')


def _read_part(part):
    """The manifest of one part directory: ``(doc, rows)``; a missing or unreadable one
    raises :class:`DatasetError` in one line naming the file."""
    path = os.path.join(part, 'manifest.json')
    if not os.path.isfile(path):
        raise DatasetError(f'{part}: no manifest.json (not a data set directory)')
    try:
        with open(path, encoding='utf-8') as f:
            doc = json.load(f)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise DatasetError(f'{path}: unreadable manifest ({reason})') from None
    rows = doc.get('runs') if isinstance(doc, dict) else None
    if not isinstance(rows, list):
        raise DatasetError(f"{path}: unreadable manifest (no 'runs' list)")
    for i, row in enumerate(rows):
        bad = None
        if not isinstance(row, dict) or not isinstance(row.get('id'), str) \
                or not _ID.match(row['id']):
            bad = 'no valid id'
        elif row.get('status') not in ('ok', 'failed'):
            bad = f"status {row.get('status')!r} is neither ok nor failed"
        elif row['status'] == 'ok' and not (isinstance(row.get('sha256'), str)
                                            and _SHA256.match(row['sha256'])):
            bad = 'an ok run without a sha256'
        if bad:
            raise DatasetError(f'{path}: unreadable manifest (run {i}: {bad})')
    return doc, rows


def _plan_entry(row):
    """A plan entry (:func:`.dataset_spec.load_spec`'s form) rebuilt from a manifest row."""
    entry = {key: row.get(column) for column, key in RUN_COLUMNS}
    entry['overrides'] = entry['overrides'] or []
    entry['keys'] = {k: v for k, v in row.items() if k not in _RUN_FIELDS}
    return entry


class _TargetError(Exception):
    """Writing the merged data set failed (its disk, not the part's log)."""


def _copy_verified(source, target, sha256, block=1 << 20):
    """Copy ``source`` to ``target`` through ``target.part``, hashing what is read; rename
    only when the digest is ``sha256``. Returns None, or the reason nothing was copied (the
    source's fault); a write error on the target raises :class:`.log_errors.LogWriteError`
    (the ``.part`` removed)."""
    from .log_errors import LogWriteError, error_reason
    digest = hashlib.sha256()
    part = target + '.part'

    def out(call, *args):   # an error here is the target disk's
        try:
            return call(*args)
        except OSError as exc:
            raise _TargetError(exc) from None
    try:
        with open(source, 'rb') as src, out(open, part, 'wb') as dst:
            for chunk in iter(lambda: src.read(block), b''):
                digest.update(chunk)
                out(dst.write, chunk)
            out(dst.flush)
            out(os.fsync, dst.fileno())
        if digest.hexdigest() != sha256:
            os.remove(part)
            return f'sha256 {digest.hexdigest()[:12]}... is not the manifest\'s {sha256[:12]}...'
        out(os.replace, part, target)
    except (OSError, _TargetError) as exc:
        with contextlib.suppress(OSError):
            os.remove(part)
        if isinstance(exc, _TargetError):
            reason = error_reason(exc.args[0])
            raise LogWriteError(f'{part}: write failed: {reason} (removed)', part,
                                reason) from None
        return f'{type(exc).__name__}: {exc.strerror or exc}'
    return None


def gather_datasets(parts, out_dir):
    """Merge data sets recorded part by part (one per machine) into ``out_dir``.

    Parameters
    ----------
    parts : list of str
        Data set directories, each with its ``manifest.json`` and ``runs/``.
    out_dir : str
        The merged data set (made if missing; may hold runs of an earlier gathering).

    Returns
    -------
    dict
        ``gathered_from`` (the part directories), ``runs`` (rows of the merged manifest),
        ``ok``, ``copied``, ``already_there``, ``duplicates`` (the same run, same bytes, in
        another part), ``failed`` (failed rows carried), ``conflicts`` (list of
        ``{id, kept, other}`` directories: the same id with other bytes; the first is kept),
        ``bad`` (list of ``{id, dir, reason}``: a log missing or not matching its sha256,
        skipped) and ``manifest`` (path).

    Raises
    ------
    DatasetError
        A part without a readable manifest (before anything is written).
    LogWriteError
        A disk error writing ``out_dir`` (a log's copy, or the manifest): gathering stops;
        the logs copied before stay (checked, under their names) and the same command
        goes on from them.
    """
    read = [(part, *_read_part(part)) for part in parts]   # every part checked first
    os.makedirs(os.path.join(out_dir, 'runs'), exist_ok=True)
    ok, failed = {}, {}   # id -> (part, row)
    result = {'copied': 0, 'already_there': 0, 'duplicates': 0, 'conflicts': [], 'bad': []}
    for part, _, rows in read:
        for row in rows:
            run_id = row['id']
            if row['status'] == 'failed':
                failed.setdefault(run_id, (part, row))
                continue
            if run_id in ok:
                first = ok[run_id][0]
                if ok[run_id][1]['sha256'] == row['sha256']:
                    result['duplicates'] += 1
                else:
                    result['conflicts'].append({'id': run_id, 'kept': first, 'other': part})
                continue
            target = os.path.join(out_dir, 'runs', run_id + '.mcap')
            if os.path.isfile(target) and file_sha256(target) == row['sha256']:
                result['already_there'] += 1
            else:
                reason = _copy_verified(os.path.join(part, 'runs', run_id + '.mcap'), target,
                                        row['sha256'])
                if reason:
                    result['bad'].append({'id': run_id, 'dir': part, 'reason': reason})
                    continue
                result['copied'] += 1
            ok[run_id] = (part, row)
    merged = {run_id: failed[run_id] for run_id in failed if run_id not in ok}
    merged.update(ok)
    plan, rows = [], {}
    for run_id in sorted(merged):
        row = merged[run_id][1]
        plan.append(_plan_entry(row))
        if row['status'] == 'ok':
            rows[run_id] = {**{k: row.get(k) for k in _OK_FIELDS},
                            'file': os.path.join('runs', run_id + '.mcap')}
        else:
            rows[run_id] = {'id': run_id, 'status': 'failed', 'error': row.get('error')}
    specs = {doc.get('spec') for _, doc, _ in read}
    spec = specs.pop() if len(specs) == 1 else None   # the parts' spec, when one
    spec = spec if isinstance(spec, str) else None
    gathered_from = [os.path.abspath(part) for part in parts]
    try:
        write_manifest(out_dir, plan, rows, spec, gathered_from=gathered_from)
    except OSError as exc:
        from .log_errors import LogWriteError, error_reason
        path = os.path.join(out_dir, 'manifest.json')
        raise LogWriteError(f'{path}: write failed: {error_reason(exc)}', path,
                            error_reason(exc)) from None
    entries = manifest_rows(plan, rows)
    result.update(gathered_from=gathered_from, runs=entries,
                  ok=sum(r['status'] == 'ok' for r in entries),
                  failed=sum(r['status'] != 'ok' for r in entries),
                  manifest=os.path.join(out_dir, 'manifest.json'))
    return result


__all__ = ['gather_datasets']
