"""The manifest of a data set (``manifest.json``, ``manifest.csv``): its columns, its
atomic writer, and the runs of an earlier manifest that stand.

One table of columns for writing a manifest and for reading it back
(:mod:`.dataset_gather`).
"""
from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import os

#: label columns of the manifest, from :func:`.record.record_log`'s result
LABELS = ('channel_preset', 'impacts_per_s', 'stuck_fraction', 'peak_g', 'rms_g', 'diverged',
          'failure', 'sim_time_s', 'wall_s', 'real_time_factor', 'messages', 'fault_labels')

#: How a manifest's ``error`` of a run failed by a disk error starts; such a run is recorded
#: again by the next ``study dataset`` without ``--retry-failed`` (the disk failed, not the run)
DISK_ERROR = 'disk error: '


def file_sha256(path, block=1 << 20):
    """The sha256 of a file's bytes (hex str), read ``block`` bytes (B) at a time."""
    digest = hashlib.sha256()
    with open(path, 'rb') as f:
        for chunk in iter(lambda: f.read(block), b''):
            digest.update(chunk)
    return digest.hexdigest()


#: a run's inputs in the manifest: (column, key of a :func:`.dataset_spec.load_spec` plan
#: entry); the grid or sample keys follow them, then the labels and the file. One table for
#: writing the manifest and for reading it back (:mod:`.dataset_gather`)
RUN_COLUMNS = (('id', 'id'), ('scene', 'scene'), ('duration_s', 'duration'),
               ('tick_period_s', 'tick_period'), ('noise_std', 'noise_std'), ('seed', 'seed'),
               ('schedule', 'schedule'), ('truth', 'truth'), ('faults', 'faults'),
               ('overrides', 'overrides'), ('inputs_sha256', 'inputs_sha256'))
#: the outcome columns of a run (the rest of a manifest row)
RESULT_COLUMNS = ('status', 'error', *LABELS, 'file', 'bytes', 'sha256')


def _columns(plan):
    """The CSV's columns: the inputs (the overrides stay in the JSON), the run's keys, the
    outcome, the inputs' digest last."""
    keys = []
    for run in plan:
        keys += [k for k in run['keys'] if k not in keys]
    inputs = [c for c, _ in RUN_COLUMNS if c not in ('id', 'overrides', 'inputs_sha256')]
    return (['id', 'status', 'error'] + inputs + keys + list(LABELS)
            + ['file', 'bytes', 'sha256', 'inputs_sha256'])


def manifest_rows(plan, rows):
    out = []
    for run in plan:
        row = rows.get(run['id'])
        if row is None:
            continue
        out.append({**{column: run[key] for column, key in RUN_COLUMNS}, **run['keys'],
                    **row})
    return out


def _write_atomic(path, text):
    """Write ``path`` whole or not at all (on disk before it replaces the old one)."""
    tmp = path + '.tmp'
    try:
        with open(tmp, 'w', encoding='utf-8', newline='') as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:   # a full disk, say: no half-written .tmp left behind
        with contextlib.suppress(OSError):
            os.remove(tmp)
        raise


def write_manifest(out_dir, plan, rows, spec_path, gathered_from=None):
    """Write ``manifest.json`` and ``manifest.csv`` of the runs finished so far (atomic).

    ``spec_path`` may be None (a gathered data set whose parts name different specs);
    ``gathered_from``, the part directories of :func:`.dataset_gather.gather_datasets`, is
    written to the JSON.
    """
    import impact_damper_sim

    from .output import strict_json
    entries = manifest_rows(plan, rows)
    doc = {'spec': None if spec_path is None else os.path.abspath(spec_path),
           'software_version': impact_damper_sim.__version__,
           'runs_planned': len(plan)}
    if gathered_from is not None:
        doc['gathered_from'] = list(gathered_from)
    doc['runs'] = entries
    _write_atomic(os.path.join(out_dir, 'manifest.json'),
                  json.dumps(strict_json(doc), indent=1) + '\n')
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=_columns(plan), extrasaction='ignore')
    writer.writeheader()
    for entry in entries:
        writer.writerow({k: _csv_text(k, v) for k, v in entry.items()})
    _write_atomic(os.path.join(out_dir, 'manifest.csv'), buf.getvalue())


def _csv_text(column, value):
    """A manifest value as its CSV cell: '' for None; the spec's faults as JSON; the fault
    labels as ``name kind accelerometer (onset_s, end_s]`` per fault, joined by ``; `` (the
    JSON holds every value and event)."""
    if value is None:
        return ''
    if column == 'fault_labels' and isinstance(value, list):
        return '; '.join(f"{f['name']} {f['kind']} {f['accelerometer']} ({f['onset_s']:g}, "
                         + ('end' if f['end_s'] is None else format(f['end_s'], 'g')) + ']'
                         for f in value)
    if isinstance(value, (list, dict)):
        return json.dumps(value, separators=(', ', ': '))
    return value


def finished_rows(out_dir, plan, retry_failed):
    """Rows of the manifest in ``out_dir`` that stand: their inputs and file unchanged."""
    path = os.path.join(out_dir, 'manifest.json')
    if not os.path.exists(path):
        return {}
    try:
        with open(path, encoding='utf-8') as f:
            old = {r['id']: r for r in json.load(f).get('runs', [])}
    except (OSError, ValueError, AttributeError, KeyError, TypeError):
        return {}   # unreadable: every run again
    keep = {}
    for run in plan:
        row = old.get(run['id'])
        if row is None or row.get('inputs_sha256') != run['inputs_sha256']:
            continue
        if row.get('status') == 'ok':
            file = os.path.join(out_dir, row.get('file') or '')
            if os.path.isfile(file) and file_sha256(file) == row.get('sha256'):
                keep[run['id']] = {k: v for k, v in row.items()
                                   if k in ('id', 'status', 'error', 'file', 'bytes', 'sha256',
                                            *LABELS)}
        elif row.get('status') == 'failed' and not retry_failed \
                and not str(row.get('error') or '').startswith(DISK_ERROR):
            # a run the disk failed is recorded again: it was not the run's failure
            keep[run['id']] = {'id': run['id'], 'status': 'failed', 'error': row.get('error')}
    return keep


__all__ = ['DISK_ERROR', 'LABELS', 'RESULT_COLUMNS', 'RUN_COLUMNS', 'file_sha256',
           'finished_rows', 'manifest_rows', 'write_manifest']
