"""Generated documents cannot go stale (issue 27 item 4; tools/generated_docs.py).

* ``docs/validation.md`` is regenerated and must equal the committed copy in every result
  (dates and wall times aside): ``test_validation_regenerates`` (``slow``; ``make test`` runs it
  first through ``make check-validation``).
* The tables printed from recorded data (``docs/fidelity.md`` from ``docs/fidelity/*.json``,
  ``docs/scenes.md``'s key table from the schema, the model pages' copies of
  ``docs/validation.md``'s tables) equal what their printers print now.
* The slow documents (``docs/convergence.md``, the impact-cost curve) record the commit and
  command that made them and a digest of their sources in ``docs/generated.json``; a test fails
  when those sources differ, naming the files and the make target that regenerates it.
"""
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location('generated_docs',
                                               ROOT / 'tools' / 'generated_docs.py')
gd = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(gd)


# --- validation: regenerated and compared ----------------------------------------------------

@pytest.mark.slow
def test_validation_regenerates(tmp_path):
    """``make validation`` on today's code gives the committed document (about 2-3 min on 2
    busy cores; 115 runs)."""
    r = subprocess.run([sys.executable, str(ROOT / 'tools' / 'generated_docs.py'), 'validation',
                        '--keep', str(tmp_path)], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, (
        'docs/validation.md differs from a regeneration on this code; run `make validation` '
        f'and commit the result if the change is meant:\n{r.stdout[-6000:]}\n{r.stderr[-2000:]}')


def test_validation_comparison_ignores_only_dates_and_wall_times():
    doc = (ROOT / 'docs' / 'validation.md').read_text()
    moved = re.sub(r' on \d{4}-\d{2}-\d{2}: ', ' on 1999-01-01: ', doc)
    moved = re.sub(r' runs in \d+ s wall time', ' runs in 12345 s wall time', moved)
    moved = re.sub(r'X = 1: \d+ s', 'X = 1: 999 s', moved)
    assert moved != doc and gd.validation_diff(moved, doc) == ''
    # a result that moves is a difference
    row = re.search(r'^\| 1 \| 4 \| 0\.7 \| 1\.4 \| [^\n]*$', doc, flags=re.M).group(0)
    cells = row.split(' | ')
    cells[5] = '9.99'
    assert gd.validation_diff(doc.replace(row, ' | '.join(cells)), doc) != ''
    # so does the header's paper link
    assert gd.validation_diff(doc.replace('](paper/impact-dampers-mdof.md)', ''), doc) != ''


def test_validation_links_the_paper():
    """The generator writes the link (it had been added by hand to the output, and a
    regeneration dropped it)."""
    doc = (ROOT / 'docs' / 'validation.md').read_text()
    assert '[`docs/paper/impact-dampers-mdof.md`](paper/impact-dampers-mdof.md)' in doc
    assert (ROOT / 'docs' / 'paper' / 'impact-dampers-mdof.md').is_file()


# --- tables printed from recorded data -------------------------------------------------------

def test_fidelity_tables_are_the_recorded_json(capsys):
    assert gd.cmd_tables(check=True) == 0, capsys.readouterr().err


def test_scene_key_table_is_the_schema(capsys):
    assert gd.cmd_keys(check=True) == 0, capsys.readouterr().err


def test_model_pages_quote_the_validation_document(capsys):
    """docs/hpotp-model.md's Table 4.3.1/4.3.2 summary and docs/rbs-model.md's Table 4.4.1
    are copies of docs/validation.md's."""
    assert gd.cmd_from_validation(check=True) == 0, capsys.readouterr().err


def test_cost_curve_table_is_the_csv():
    """The table docs/impact-cost.md prints under the curve is its CSV, as the bench prints it."""
    want = gd.cost_curve_rows()
    page = (ROOT / 'docs' / 'impact-cost.md').read_text()
    section = page.split('## Cost curve', 1)[1]
    block = re.search(r'```\nimpactors modes[^\n]*\n(.*?)```', section, flags=re.S).group(1)
    assert block.splitlines() == want, ('docs/impact-cost.md quotes another cost curve than '
                                        'docs/impact-cost/cost_curve.csv')


# --- slow documents: commit, command and the digest of their sources -------------------------

@pytest.mark.parametrize('name', sorted(gd.SLOW))
def test_slow_document_records_its_commit_and_command(name):
    entry = gd.load_manifest().get(name)
    assert entry, f'docs/generated.json has no record of {name}; run `{gd.SLOW[name]["target"]}`'
    assert re.fullmatch(r'[0-9a-f]{7,40}( with uncommitted changes)?', entry['commit'])
    assert entry['command'] and entry['target'] == gd.SLOW[name]['target']
    assert entry['digest'] == gd.total_digest(entry['files'])
    page = (ROOT / gd.SLOW[name]['stamp_page']).read_text()
    stamp = [line for line in page.splitlines() if line.endswith(f'<!-- stamp:{name} -->')]
    assert len(stamp) == 1 and f'`{entry["commit"]}`' in stamp[0] \
        and f'`{entry["digest"]}`' in stamp[0], f'{gd.SLOW[name]["stamp_page"]}: stamp line'
    for out in entry['outputs']:
        assert list(ROOT.glob(out)), out


@pytest.mark.parametrize('name', sorted(gd.SLOW))
def test_slow_document_sources_unchanged(name):
    """Fails when the code a slow document depends on changed after it was made."""
    problems = gd.stale(name)
    assert not problems, problems[0]


def test_digest_sees_a_change():
    """The digest covers the engine: a changed kernel or scene file is a change."""
    files = gd.file_digests('convergence')
    assert 'impact_damper_sim/integrate/kernels/exact.py' in files
    assert 'config/scenes/hpotp.yaml' in files
    assert not any(p.startswith(('impact_damper_sim/ros/', 'impact_damper_sim/cli/'))
                   for p in files)
    changed = dict(files, **{'config/scenes/hpotp.yaml': '0' * 16})
    assert gd.total_digest(changed) != gd.total_digest(files)


# --- what the README and docs quote ----------------------------------------------------------

def _shipped_scenes():
    return sorted(p.stem for p in (ROOT / 'config' / 'scenes').glob('*.yaml'))


def test_scene_lists_name_every_shipped_scene():
    scenes = _shipped_scenes()
    study = (ROOT / 'docs' / 'study.md').read_text()
    listed = re.search(r'`SCENE` is a shipped scene name \(([^)]*)\)', study, flags=re.S).group(1)
    assert sorted(re.findall(r'`(\w+)`', listed.split(':')[0])) == scenes
    table = (ROOT / 'docs' / 'scenes.md').read_text().split('| scene | what it is |')[1]
    table = table.split('\n\n')[0]
    assert sorted(re.findall(r'^\| `(\w+)` \|', table, flags=re.M)) == scenes


def test_every_picture_in_the_docs_exists():
    """Plots a page shows are files of the checkout (a renamed or dropped plot is caught)."""
    missing = []
    for page in [ROOT / 'README.md', *sorted((ROOT / 'docs').glob('*.md'))]:
        for target in re.findall(r'!\[[^\]]*\]\(([^)\s]+)\)', page.read_text()):
            if not (page.parent / target).is_file():
                missing.append(f'{page.relative_to(ROOT)}: {target}')
    assert not missing, missing


def test_readme_quotes_no_typed_run_times_of_generated_documents():
    """The README points at the documents for their run times instead of typing them (the
    typed '5 min' of make validation had become wrong)."""
    readme = (ROOT / 'README.md').read_text()
    for target in ('make validation', 'make convergence', 'make impact-cost'):
        line = [ln for ln in readme.splitlines() if ln.startswith(f'| `{target}`')]
        assert len(line) == 1, target
        assert not re.search(r'\d+(\.\d+)? ?(s|min|minutes)\b', line[0]), line[0]
