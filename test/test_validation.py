"""``study validate --quick``: the validation document's sections and paper columns."""
import time

from impact_damper_sim.cli.study import main
from impact_damper_sim.studies.validation import SECTIONS


def test_validate_quick_writes_every_section(tmp_path, capsys):
    out = tmp_path / 'validation.md'
    start = time.perf_counter()
    status = main(['validate', '--quick', '--out', str(out), '--workers', '1'])
    wall = time.perf_counter() - start
    _, err = capsys.readouterr()
    assert status == 0, err
    assert wall < 60
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
