"""``study dataset``: a grid or a seeded sample of node logs, a manifest with labels and
sha256, one failing run recorded without stopping the rest, and resuming where it stopped."""
import csv
import hashlib
import json
import os

import pytest

from impact_damper_sim.studies.dataset import run_dataset
from impact_damper_sim.studies.dataset_spec import DatasetError, load_spec

SPEC = """\
scene: sdof
duration: 300 ms
noise_std: 0.01 g
grid:
  impactors.0.cor: [0.5, 0.7, 5]
seeds: [0, 1]
"""


def _write(tmp_path, text, name='spec.yaml'):
    path = tmp_path / name
    path.write_text(text)
    return path


def _manifest(out):
    with open(out / 'manifest.json') as f:
        doc = json.load(f)
    with open(out / 'manifest.csv', newline='') as f:
        rows = list(csv.DictReader(f))
    return doc, rows


def test_a_bad_spec_names_every_problem(tmp_path):
    spec = _write(tmp_path, 'scene: sdof\nduration: -1 s\ngrid: {a: []}\nseeds: [x]\n'
                            'schedules: [missing.yaml]\ncolour: red\n')
    with pytest.raises(DatasetError) as info:
        load_spec(spec)
    text = str(info.value)
    assert text.startswith(f'invalid data set spec {spec} (5 errors):')
    for part in ("key 'colour': unknown", "key 'duration': -1 s must be > 0",
                 "key 'grid': expected a mapping", "key 'seeds': expected a list of integers",
                 "key 'schedules[0]': schedule file"):
        assert part in text, part


def test_a_grid_gives_one_labelled_log_per_run_and_a_failing_run_its_reason(tmp_path):
    spec = _write(tmp_path, SPEC)
    out = tmp_path / 'data'
    result = run_dataset(str(spec), str(out), executor='serial')
    assert (result['planned'], result['recorded'], result['failed']) == (6, 6, 2)
    doc, rows = _manifest(out)
    assert [r['id'] for r in doc['runs']] == [r['id'] for r in rows]
    assert [(r['impactors.0.cor'], r['seed']) for r in rows] == [
        ('0.5', '0'), ('0.5', '1'), ('0.7', '0'), ('0.7', '1'), ('5', '0'), ('5', '1')]
    ok = [r for r in doc['runs'] if r['status'] == 'ok']
    failed = [r for r in doc['runs'] if r['status'] == 'failed']
    assert len(ok) == 4 and len(failed) == 2
    assert all("impactors[0].cor': 5 is out of range [0, 1]" in r['error'] for r in failed)
    assert all('\n' not in r['error'] for r in failed)
    for r in ok:
        data = (out / r['file']).read_bytes()
        assert hashlib.sha256(data).hexdigest() == r['sha256'] and len(data) == r['bytes']
        assert r['diverged'] is False and r['sim_time_s'] == pytest.approx(0.3)
        assert r['peak_g'] > r['rms_g'] > 0 and 0 <= r['stuck_fraction'] <= 1
    assert sorted(p.name for p in (out / 'runs').iterdir()) == sorted(
        os.path.basename(r['file']) for r in ok)   # no .part left behind
    # the noise seed changes the samples, the same seed and inputs give the same bytes
    by = {(r['impactors.0.cor'], r['seed']): r for r in doc['runs']}
    assert by[(0.5, 0)]['sha256'] != by[(0.5, 1)]['sha256']
    run_dataset(str(spec), str(tmp_path / 'again'), executor='serial')
    # file creation time aside, a log is its inputs: compare the message data
    from test_record import _messages
    first = _messages(out / by[(0.7, 1)]['file'])
    second = _messages(tmp_path / 'again' / by[(0.7, 1)]['file'])
    assert first == second


def test_tick_period_is_a_run_input_and_a_manifest_column(tmp_path):
    """tick_period: 50 ms is checked, recorded into every run's log (full-rate batches of
    50 ms of samples), listed after duration_s in both manifests, and part of the run id."""
    import yaml
    from mcap.reader import make_reader

    from test_record import _messages
    text = 'scene: sdof\nduration: 100 ms\ntick_period: 50 ms\ngrid:\n  impactors.0.cor: [0.6]\n'
    spec = _write(tmp_path, text)
    (run,) = load_spec(spec)
    assert run['tick_period'] == pytest.approx(0.05, rel=1e-15)
    default = load_spec(_write(tmp_path, text.replace('tick_period: 50 ms\n', ''), 'd.yaml'))
    explicit = load_spec(_write(tmp_path, text.replace('50 ms', '0.01'), 'e.yaml'))
    assert default[0]['tick_period'] == 0.01 and explicit[0]['id'] == default[0]['id']
    assert run['id'] != default[0]['id']   # a changed tick_period is another run
    out = tmp_path / 'data'
    result = run_dataset(str(spec), str(out), executor='serial')
    assert (result['recorded'], result['failed']) == (1, 0)
    doc, rows = _manifest(out)
    assert doc['runs'][0]['tick_period_s'] == pytest.approx(0.05, rel=1e-15)
    assert float(rows[0]['tick_period_s']) == pytest.approx(0.05, rel=1e-15)
    columns = list(rows[0])
    assert columns[:7] == ['id', 'status', 'error', 'scene', 'duration_s', 'tick_period_s',
                           'noise_std']
    log = out / doc['runs'][0]['file']
    with open(log, 'rb') as f:
        meta = {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}
    params = yaml.safe_load(meta['impact_damper_sim']['node_parameters'])
    assert params['tick_period'] == pytest.approx(0.05, rel=1e-15)
    widths = [m[4].width for m in _messages(log, decode=True) if m[0].endswith('/batch')]
    assert params['sample_rate'] == 2000 and widths == [100, 100]   # 2 ticks of 50 ms
    # the same spec again: the run is there, nothing is recorded
    assert run_dataset(str(spec), str(out), executor='serial')['skipped'] == 1


@pytest.mark.parametrize('value, reason', [
    ('0', '0 is out of range'), ('500 ms', '500 ms is out of range'),
    ('5 kg', "unit 'kg' is not a time"), ('abc', "cannot read 'abc' as a time")])
def test_a_bad_tick_period_names_the_key_and_the_range(tmp_path, value, reason):
    spec = _write(tmp_path, f'scene: sdof\nduration: 0.1\ntick_period: {value}\n')
    with pytest.raises(DatasetError) as info:
        load_spec(spec)
    assert str(info.value).startswith(f"{spec}: key 'tick_period': {reason}")
    assert str(info.value).endswith('[0.001, 0.1] s') and '\n' not in str(info.value)


def test_an_interrupted_data_set_continues_where_it_stopped(tmp_path):
    spec = _write(tmp_path, SPEC.replace('[0.5, 0.7, 5]', '[0.5, 0.7]'))
    out = tmp_path / 'data'
    run_dataset(str(spec), str(out), executor='serial')
    doc, _ = _manifest(out)
    runs = doc['runs']
    # an interruption: the last run never reached the manifest and left a partial file;
    # another run's log was damaged since
    lost, damaged = runs[-1], runs[0]
    doc['runs'] = runs[:-1]
    (out / 'manifest.json').write_text(json.dumps(doc))
    (out / lost['file']).rename(out / (lost['file'] + '.part'))
    (out / damaged['file']).write_bytes(b'not a log')
    kept = {r['id']: (out / r['file']).stat().st_mtime_ns for r in runs[1:-1]}
    result = run_dataset(str(spec), str(out), executor='serial')
    assert (result['planned'], result['skipped'], result['recorded']) == (4, 2, 2)
    assert {r['id']: (out / r['file']).stat().st_mtime_ns for r in runs[1:-1]} == kept
    doc2, _ = _manifest(out)
    assert [(r['id'], r['sha256']) for r in doc2['runs']] == [
        (r['id'], r['sha256']) for r in runs]   # the same logs again, byte for byte
    # a changed input is a new run; the unchanged ones are still skipped
    spec.write_text(SPEC.replace('[0.5, 0.7, 5]', '[0.5, 0.6]'))
    result = run_dataset(str(spec), str(out), executor='serial')
    assert (result['skipped'], result['recorded']) == (2, 2)


def test_a_run_a_disk_error_failed_is_recorded_again_without_retry_failed(tmp_path,
                                                                          monkeypatch):
    """A disk error is the disk's failure, not the run's: it stops the data set, and the
    next run of the command records that run again; a run that failed on its own stays
    failed (unless --retry-failed)."""
    import impact_damper_sim.studies.record as record
    from impact_damper_sim.studies.log_errors import LogWriteError
    spec = _write(tmp_path, SPEC)
    out = tmp_path / 'data'
    real = record.record_log
    calls = []

    def full_disk(scene, out_path, *args, **kwargs):   # the third run hits a full disk
        calls.append(out_path)
        if len(calls) == 3:
            with open(out_path, 'wb') as f:
                f.write(b'partial')
            raise LogWriteError(f'{out_path}: write failed: No space left on device',
                                out_path, 'write failed: No space left on device')
        return real(scene, out_path, *args, **kwargs)

    monkeypatch.setattr(record, 'record_log', full_disk)
    result = run_dataset(str(spec), str(out), executor='serial')
    assert result['stopped'] and 'No space left on device' in result['stopped']
    assert (result['recorded'], result['not_started']) == (3, 3)   # stopped at the error
    doc, rows = _manifest(out)
    failed = [r for r in doc['runs'] if r['status'] == 'failed']
    assert len(failed) == 1 and failed[0]['error'].startswith('disk error: ')
    assert 'unfinished log was removed' in failed[0]['error']
    assert not list((out / 'runs').glob('*.part'))
    assert 'disk_error' not in doc['runs'][0] and rows[2]['status'] == 'failed'
    monkeypatch.setattr(record, 'record_log', real)   # space made
    result = run_dataset(str(spec), str(out), executor='serial')
    assert result['stopped'] is None
    assert (result['skipped'], result['recorded'], result['failed']) == (2, 4, 2)
    doc, _ = _manifest(out)
    assert not any(str(r['error']).startswith('disk error') for r in doc['runs'])


def test_a_seeded_sample_draws_the_same_runs_every_time(tmp_path):
    text = ('scene: sdof\nduration: 0.1\nsample:\n  n: 5\n  seed: 3\n  keys:\n'
            '    impactors.0.clearance: {low: 1.5, high: 4, unit: mm}\n'
            '    impactors.0.cor: [0.5, 0.6]\n')
    spec = _write(tmp_path, text)
    plan = load_spec(spec)
    assert [r['id'] for r in plan] == [r['id'] for r in load_spec(spec)]
    assert len({r['id'] for r in plan}) == 5
    for run in plan:
        value, unit = run['keys']['impactors.0.clearance'].split()
        assert unit == 'mm' and 1.5 <= float(value) <= 4
        assert run['keys']['impactors.0.cor'] in (0.5, 0.6)
        assert run['overrides'][0].startswith('impactors.0.clearance=')
    other = load_spec(_write(tmp_path, text.replace('seed: 3', 'seed: 4'), 'other.yaml'))
    assert {r['id'] for r in other}.isdisjoint(r['id'] for r in plan)


def test_the_command_line_and_a_process_pool(tmp_path, capsys):
    from impact_damper_sim.cli.study import main
    spec = _write(tmp_path, SPEC)
    out = tmp_path / 'data'
    assert main(['dataset', str(spec), '--out', str(out), '--workers', '2',
                 '--progress']) == 1   # two runs fail
    captured = capsys.readouterr()
    assert '6 runs planned: 0 already done, 6 recorded now, 2 failed' in captured.out
    assert captured.err.count('study: error: run r') == 2
    assert 'dataset 6/6 runs, 2 failed' in captured.err and 'runs/s' in captured.err
    assert main(['dataset', str(spec), '--out', str(out), '--json']) == 1
    summary = json.loads(capsys.readouterr().out)
    assert (summary['skipped'], summary['recorded']) == (6, 0)
    assert main(['dataset', str(tmp_path / 'nope.yaml'), '--out', str(out)]) == 2


def test_a_dask_cluster_records_the_same_logs(tmp_path):
    distributed = pytest.importorskip('distributed')
    from test_record import _messages
    spec = _write(tmp_path, SPEC.replace('[0.5, 0.7, 5]', '[0.6]'))
    serial = run_dataset(str(spec), str(tmp_path / 'serial'), executor='serial')
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        dask = run_dataset(str(spec), str(tmp_path / 'dask'), executor='dask',
                           dask_address=cluster.scheduler_address)
    assert dask['failed'] == 0 and [r['id'] for r in dask['rows']] == [
        r['id'] for r in serial['rows']]
    for a, b in zip(serial['rows'], dask['rows']):
        assert _messages(tmp_path / 'serial' / a['file']) == _messages(
            tmp_path / 'dask' / b['file'])


GATHER_SPEC = 'scene: sdof\nduration: 100 ms\ngrid:\n  impactors.0.cor: {cors}\nseeds: [0, 1]\n'


def _parts(tmp_path):
    """Two slices of one grid, each recorded into its own directory (two machines)."""
    dirs = []
    for name, cors in (('a', '[0.5]'), ('b', '[0.7, 5]')):
        spec = _write(tmp_path, GATHER_SPEC.format(cors=cors), f'{name}.yaml')
        run_dataset(str(spec), str(tmp_path / name), executor='serial')
        dirs.append(tmp_path / name)
    return dirs


def test_parts_recorded_apart_are_gathered_into_one_data_set(tmp_path, capsys):
    from impact_damper_sim.cli.study import main
    a, b = _parts(tmp_path)
    out = tmp_path / 'all'
    assert main(['dataset', '--gather', str(a), str(b), '--out', str(out)]) == 0
    line = capsys.readouterr().out
    assert line.startswith('6 runs gathered from 2 directories: 4 copied, 0 already there, '
                           '0 conflicts, 0 bad logs skipped, 2 failed; manifest ')
    parts = {r['id']: (d, r) for d in (a, b) for r in _manifest(d)[0]['runs']}
    doc, rows = _manifest(out)
    assert doc['gathered_from'] == [str(a), str(b)]
    assert [r['id'] for r in doc['runs']] == sorted(parts) == [r['id'] for r in rows]
    for r in doc['runs']:
        d, src = parts[r['id']]
        assert r == src   # the same row: parameters, labels, status, reason, sha256
        if r['status'] == 'ok':
            assert (out / r['file']).read_bytes() == (d / src['file']).read_bytes()
    assert sorted(p.name for p in (out / 'runs').iterdir()) == sorted(
        r['id'] + '.mcap' for r in doc['runs'] if r['status'] == 'ok')   # no .part left
    assert list(rows[0]) == list(_manifest(a)[1][0])   # the same CSV columns
    # the full spec recognises every gathered run: nothing is recorded again
    full = _write(tmp_path, GATHER_SPEC.format(cors='[0.5, 0.7, 5]'), 'full.yaml')
    result = run_dataset(str(full), str(out), executor='serial')
    assert result['skipped'] == result['planned'] == 6 and result['recorded'] == 0
    # gathering again copies nothing
    mtimes = {p.name: p.stat().st_mtime_ns for p in (out / 'runs').iterdir()}
    assert main(['dataset', '--gather', str(a), str(b), '--out', str(out), '--json']) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary['copied'], summary['already_there'], summary['ok'],
            summary['failed']) == (0, 4, 4, 2)
    assert {p.name: p.stat().st_mtime_ns for p in (out / 'runs').iterdir()} == mtimes


def test_a_tampered_log_is_skipped_and_a_conflict_is_reported(tmp_path, capsys):
    from impact_damper_sim.cli.study import main
    a, b = _parts(tmp_path)
    ok = [r for r in _manifest(a)[0]['runs'] if r['status'] == 'ok']
    data = bytearray((a / ok[0]['file']).read_bytes())
    data[len(data) // 2] ^= 0xFF   # one byte changed
    (a / ok[0]['file']).write_bytes(bytes(data))
    out = tmp_path / 'all'
    assert main(['dataset', '--gather', str(a), str(b), '--out', str(out)]) == 1
    captured = capsys.readouterr()
    assert '3 copied, 0 already there, 0 conflicts, 1 bad logs skipped' in captured.out
    assert f"run {ok[0]['id']} in {a}: sha256 " in captured.err
    assert not (out / ok[0]['file']).exists()
    ids = [r['id'] for r in _manifest(out)[0]['runs']]
    assert ok[0]['id'] not in ids and ok[1]['id'] in ids   # the others went on
    # a third part that holds one of a's runs with other bytes: a conflict, a's is kept
    c = tmp_path / 'c'
    (c / 'runs').mkdir(parents=True)
    doc = json.loads((a / 'manifest.json').read_text())
    row = dict(ok[1], sha256=hashlib.sha256(b'other').hexdigest())
    doc['runs'] = [row]
    (c / 'manifest.json').write_text(json.dumps(doc))
    (c / row['file']).write_bytes(b'other')
    assert main(['dataset', '--gather', str(a), str(c), '--out', str(out), '--json']) == 1
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    assert summary['conflicts'] == [{'id': row['id'], 'kept': str(a), 'other': str(c)}]
    assert f"run {row['id']}: {a} and {c} hold different logs" in captured.err
    assert (out / row['file']).read_bytes() == (a / row['file']).read_bytes()


def test_a_part_without_a_readable_manifest_is_refused(tmp_path, capsys):
    from impact_damper_sim.cli.study import main
    a, _ = _parts(tmp_path)
    empty = tmp_path / 'empty'
    empty.mkdir()
    out = tmp_path / 'all'
    assert main(['dataset', '--gather', str(a), str(empty), '--out', str(out)]) == 2
    err = capsys.readouterr().err
    assert err.strip() == f'study: error: {empty}: no manifest.json (not a data set directory)'
    (empty / 'manifest.json').write_text('{"runs": [')
    assert main(['dataset', '--gather', str(a), str(empty), '--out', str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and f"{empty / 'manifest.json'}: unreadable manifest" in err
    assert not out.exists()   # nothing written
    assert main(['dataset', str(tmp_path / 'a.yaml'), '--gather', str(a),
                 '--out', str(out)]) == 2
    assert 'SPEC.yaml cannot be given with --gather' in capsys.readouterr().err


def test_the_manifest_names_each_runs_channel_preset_and_truth_is_a_run_input(tmp_path):
    """A grid over the scene's ``channel``: the manifest gives each run's preset, the log's
    metadata holds its labels; ``truth: true`` writes the ground truth into every log, is a
    manifest column and part of the run id (a spec without it keeps its ids)."""
    import yaml

    from test_tach_truth import _log
    text = 'scene: sdof\nduration: 50 ms\ngrid:\n  channel: [ideal, iepe_100mv_50g]\n'
    spec = _write(tmp_path, text + 'truth: true\n')
    plan = load_spec(spec)
    without = load_spec(_write(tmp_path, text, 'without.yaml'))
    explicit = load_spec(_write(tmp_path, text + 'truth: false\n', 'false.yaml'))
    assert [r['truth'] for r in plan] == [True, True]
    assert [r['truth'] for r in without] == [False, False]
    assert [r['id'] for r in explicit] == [r['id'] for r in without]
    assert not {r['id'] for r in plan} & {r['id'] for r in without}
    with pytest.raises(DatasetError, match=r"key 'truth': expected true or false, got 2"):
        load_spec(_write(tmp_path, text + 'truth: 2\n', 'bad.yaml'))
    out = tmp_path / 'data'
    assert run_dataset(str(spec), str(out), executor='serial')['failed'] == 0
    doc, rows = _manifest(out)
    assert [r['channel_preset'] for r in rows] == ['ideal', 'iepe_100mv_50g']
    assert [r['channel_preset'] for r in doc['runs']] == ['ideal', 'iepe_100mv_50g']
    assert [r['truth'] for r in rows] == ['True', 'True']
    for run in doc['runs']:
        topics, meta = _log(out / run['file'])
        labels = yaml.safe_load(meta['labels'])
        (name, accelerometer), = labels['accelerometers'].items()
        assert accelerometer['channel']['preset'] == run['channel_preset']
        assert len(topics[f'/accel/{name}/truth']) == len(topics[f'/accel/{name}/batch']) == 5
        assert labels['seed'] == run['seed'] == 0
