"""Generated documents cannot go stale (issue 27 item 4; tools/generated_docs.py).

* ``docs/validation.md`` is regenerated and must equal the committed copy in every result
  (dates and wall times aside): ``test_validation_regenerates`` (``slow``; ``make test`` runs it
  first through ``make check-validation``).
* The tables printed from recorded data (``docs/fidelity.md`` from ``docs/fidelity/*.json``,
  ``docs/scenes.md``'s key table from the schema, the model pages' copies of
  ``docs/validation.md``'s tables) equal what their printers print now.
* The slow documents (``docs/convergence.md``, the impact-cost curve) record the commit and
  command that made them and a digest of their sources in ``docs/generated.json``; a test fails
  when those sources differ, naming the files and the make target that regenerates it. The
  digests see code and data, not comments, docstrings or layout (issue 37 item 5): a comment
  edit needs no ``accept``.
"""
import ast
import importlib.util
import re
import shutil
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
    assert len(stamp) == 1 and entry['date'] in stamp[0] \
        and f'`{entry["digest"]}`' in stamp[0], f'{gd.SLOW[name]["stamp_page"]}: stamp line'
    # a reader's page says when and where it was made, not which commit (issue 38)
    assert entry['commit'].split()[0] not in stamp[0] and 'commit' not in stamp[0]
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
    assert any(p.startswith('impact_damper_sim/integrate/kernels/') for p in files)
    assert 'config/scenes/hpotp.yaml' in files
    assert not any(p.startswith(('impact_damper_sim/ros/', 'impact_damper_sim/cli/'))
                   for p in files)
    changed = dict(files, **{'config/scenes/hpotp.yaml': '0' * 16})
    assert gd.total_digest(changed) != gd.total_digest(files)


# --- digests by what can change a result (issue 37 item 5) ----------------------------------

_MODULE = '''"""A module."""
import math

RATE = 2.5   # per second


class Spring:
    """A spring."""

    def force(self, x):
        """Force at ``x``."""
        return -RATE * x + math.sin(x)
'''


def test_python_digest_ignores_comments_docstrings_and_layout():
    base = gd.python_code_digest(_MODULE)
    same = [
        _MODULE.replace('# per second', '# per second, say why at length'),
        _MODULE.replace('"""A spring."""', '"""A spring, documented.\n\n    More.\n    """'),
        _MODULE.replace('"""A module."""', "'Another module docstring.'"),
        _MODULE.replace('"""A module."""\n', ''),                        # docstring removed
        _MODULE.replace('return -RATE * x + math.sin(x)',
                        'return (-RATE * x\n                + math.sin(x))  # re-wrapped'),
        _MODULE.replace('\n\n\nclass', '\n# a comment line\n\n\n\nclass'),
        _MODULE.replace('RATE = 2.5', 'RATE = 2.50'),                    # the same float
    ]
    assert [gd.python_code_digest(t) == base for t in same] == [True] * len(same)
    moved = [
        _MODULE.replace('RATE = 2.5', 'RATE = 2.6'),                     # a constant
        _MODULE.replace('-RATE * x +', '-RATE * x -'),                   # an operator
        _MODULE.replace('math.sin', 'math.cos'),                         # a name
        _MODULE.replace('        return', '        x = abs(x)\n        return'),  # a statement
        _MODULE.replace('import math\n', 'import math\nimport cmath as math\n'),
    ]
    assert len({gd.python_code_digest(t) for t in moved} | {base}) == len(moved) + 1


def test_real_source_digest_ignores_a_comment_but_not_a_constant():
    """On an engine file: a comment and a docstring edit keep its digest; a changed number
    does not."""
    path = 'impact_damper_sim/dampers/law.py'
    data = (ROOT / path).read_bytes()
    text = data.decode()
    base = gd.source_digest(path, data)
    commented = '# a comment edit\n' + text.replace('"""', '"""Reworded. ', 1)
    assert commented != text and gd.source_digest(path, commented.encode()) == base
    number = next(n for n in ast.walk(ast.parse(text)) if isinstance(n, ast.Constant)
                  and type(n.value) in (int, float))       # a number of the code
    lines = text.splitlines(True)
    line = lines[number.lineno - 1]
    lines[number.lineno - 1] = (line[:number.col_offset] + repr(number.value * 2 + 1)
                                + line[number.end_col_offset:])
    assert gd.source_digest(path, ''.join(lines).encode()) != base
    # a file that does not parse (half-edited) falls back to its bytes: any change shows
    assert gd.source_digest(path, b'def (') != gd.source_digest(path, b'def ( ')


def test_yaml_digest_ignores_comments_but_not_values():
    """Scene files by their parsed events: a comment or a layout change keeps the digest, a
    value (even an equal number written another way) changes it."""
    path = 'config/scenes/sdof.yaml'
    text = (ROOT / path).read_text()
    base = gd.source_digest(path, text.encode())
    assert 'mass: 2 kg                                # primary (housing) mass M' in text
    assert '  - {name: primary, node: 0, dof: uy}\n' in text
    same = [
        '# a new header comment\n' + text,
        text.replace('# primary (housing) mass M', '# M, the housing'),
        text.replace('mass: 2 kg                                #', 'mass: 2 kg  #'),
        text.replace('  - {name: primary, node: 0, dof: uy}\n',
                     '  - name: primary\n    node: 0\n    dof: uy\n'),       # flow -> block
    ]
    assert [gd.source_digest(path, t.encode()) == base for t in same] == [True] * len(same)
    moved = [text.replace('mass: 2 kg ', 'mass: 3 kg '),
             text.replace('damping_ratio: 0.02 ', 'damping_ratio: 2e-2 '),   # read differently
             text.replace('  n_modes: 1\n', '  n_modes: 1\n  extra: 1\n'),
             text.replace('mass: 2 kg ', "mass: '2 kg'")]                     # quoted
    assert all(t != text for t in moved)
    assert [gd.source_digest(path, t.encode()) != base for t in moved] == [True] * len(moved)


def test_other_files_keep_a_byte_digest():
    assert gd.source_digest('docs/x.csv', b'a,b\n1,2\n') != gd.source_digest(
        'docs/x.csv', b'a,b\n1,2 \n')


_COPIED = ['impact_damper_sim/__init__.py', 'impact_damper_sim/dampers/law.py',
           *[f'config/scenes/{s}.yaml' for s in ('cantilever', 'hpotp', 'rbs_kcc', 'sdof')]]


def test_accept_records_code_digests_that_ignore_a_comment(tmp_path, monkeypatch):
    """``accept`` on a small copy of the checkout (a few engine files, the scenes, the page and
    docs/generated.json): the record carries the digest method, the check then passes, still
    passes after a comment edit, and fails naming the file after a change of code."""
    for rel in _COPIED + ['docs/convergence.md', 'docs/generated.json']:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(ROOT / rel, tmp_path / rel)
    monkeypatch.setattr(gd, 'ROOT', tmp_path)
    monkeypatch.setattr(gd, 'MANIFEST', tmp_path / 'docs' / 'generated.json')
    old = gd.load_manifest()['convergence']
    if old.get('digest_method') != gd.DIGEST_METHOD:
        assert 'made another way' in gd.stale('convergence')[0]
    gd.cmd_accept('convergence', 'test: comments only')
    entry = gd.load_manifest()['convergence']
    assert entry['digest_method'] == gd.DIGEST_METHOD
    assert sorted(entry['files']) == sorted(_COPIED)
    assert entry['commit'] == old['commit'] and entry['accepted']['reason'] == 'test: comments only'
    assert f'`{entry["digest"]}`' in (tmp_path / 'docs' / 'convergence.md').read_text()
    assert gd.stale('convergence') == []
    law = tmp_path / 'impact_damper_sim' / 'dampers' / 'law.py'
    law.write_text('# a comment added after the accept\n' + law.read_text())
    scene = tmp_path / 'config' / 'scenes' / 'hpotp.yaml'
    scene.write_text(scene.read_text() + '\n# a trailing comment\n')
    assert gd.stale('convergence') == []
    law.write_text(law.read_text() + '\nEXTRA = 1\n')
    problems = gd.stale('convergence')
    assert len(problems) == 1 and '1 changed: impact_damper_sim/dampers/law.py' in problems[0]


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
