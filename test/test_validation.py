"""``study validate --quick``: the validation document's sections and paper columns."""
import time

from impact_damper_sim.cli.study import main
from impact_damper_sim.studies.validation_doc import SECTIONS


def test_validate_quick_writes_every_section(tmp_path, capsys):
    out = tmp_path / 'validation.md'
    start = time.perf_counter()
    status = main(['validate', '--quick', '--out', str(out), '--workers', '1'])
    wall = time.perf_counter() - start
    _, err = capsys.readouterr()
    assert status == 0, err
    print(f'\nvalidate --quick: {wall:.1f} s wall (a figure, not a test: timing is for bench/)')
    text = out.read_text()
    for heading in SECTIONS:
        assert f'## {heading}' in text
    # the paper's columns next to ours
    for column in ('paper without (F0/K)', 'paper disp (mil)', 'paper acc (g)',
                   'paper without (g)', 'paper with (g)', 'paper rms (mil)',
                   'paper impacts/s', '222,000'):
        assert column in text, column
    assert 'not run in quick mode' in text
    assert (tmp_path / 'validation' / 'frf.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert (tmp_path / 'validation' / 'rbs_stability.png').exists()


def test_validate_rejects_bad_workers(capsys):
    assert main(['validate', '--quick', '--workers', '0']) == 2
    assert '--workers' in capsys.readouterr().err


def test_validate_quick_never_writes_the_full_document_and_refuses_to_overwrite(
        tmp_path, capsys, monkeypatch):
    """--quick writes validation-quick.md by default, never docs/validation.md; an existing
    document or plot is only replaced with --overwrite (refused before any run)."""
    monkeypatch.chdir(tmp_path)
    docs = tmp_path / 'docs'
    docs.mkdir()
    (docs / 'validation.md').write_text('full document')
    calls = []
    import impact_damper_sim.studies.validation as validation

    def fake(out, **kw):
        calls.append(out)
        return {'path': out, 'plots': {'frf': 'x/frf.png'}, 'n_points': 0, 'wall_time_s': 0.0,
                'failures': []}
    monkeypatch.setattr(validation, 'validate', fake)
    assert main(['validate', '--quick']) == 0
    assert calls == ['validation-quick.md']
    assert (docs / 'validation.md').read_text() == 'full document'
    capsys.readouterr()
    assert main(['validate', '--quick', '--out', 'docs/validation.md']) == 2
    assert 'docs/validation.md exists; pass --overwrite' in capsys.readouterr().err
    assert len(calls) == 1   # refused before running anything
    (tmp_path / 'validation-quick').mkdir()
    (tmp_path / 'validation-quick' / 'frf.png').write_bytes(b'png')
    assert main(['validate', '--quick']) == 2
    assert 'validation-quick/frf.png' in capsys.readouterr().err
    assert main(['validate', '--quick', '--overwrite']) == 0
    assert calls == ['validation-quick.md', 'validation-quick.md']
