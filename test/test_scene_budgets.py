"""Scene files under abuse: every bad file is refused in one line before anything is built,
by the loader that ``study`` and ``vibration_node`` share, within bounded time and memory."""
import os
import time

import pytest

from impact_damper_sim.scene import loading
from impact_damper_sim.scene.build import load
from impact_damper_sim.scene.loading import MAX_SCENE_BYTES, MAX_SCENE_DEPTH, load_yaml
from impact_damper_sim.scene.model_budget import MAX_IMPACTORS
from impact_damper_sim.scene.schema import SceneError
from node_refusal import node_refusal

BOMB = """a: &a [x, x, x, x, x, x, x, x, x, x]
b: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a, *a]
c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b, *b]
d: &d [*c, *c, *c, *c, *c, *c, *c, *c, *c, *c]
e: &e [*d, *d, *d, *d, *d, *d, *d, *d, *d, *d]
f: &f [*e, *e, *e, *e, *e, *e, *e, *e, *e, *e]
g: &g [*f, *f, *f, *f, *f, *f, *f, *f, *f, *f]
h: &h [*g, *g, *g, *g, *g, *g, *g, *g, *g, *g]
i: &i [*h, *h, *h, *h, *h, *h, *h, *h, *h, *h]
sensors: [*i, *i, *i, *i, *i, *i, *i, *i, *i, *i]
"""


def test_an_alias_bomb_is_refused_at_once():
    """10 levels of 10 aliases: 1e10 values expanded (it took 3 GB and 200 s before)."""
    t0 = time.process_time()
    with pytest.raises(SceneError, match=r'<text>:\d+: more than 1,000,000 values once its '
                                         r'aliases are expanded'):
        load_yaml(BOMB)
    assert time.process_time() - t0 < 1.0   # CPU, not wall: what the check itself costs


@pytest.mark.parametrize('libyaml', [True, False], ids=['libyaml', 'pure-python'])
@pytest.mark.parametrize('style', ['flow', 'block'])
def test_one_impactor_over_the_limit_is_refused_on_its_line(libyaml, style):
    """The event pre-scan counts the top-level ``impactors`` list and refuses item
    ``MAX_IMPACTORS + 1`` on its own line (this error path read a name ``limit`` that only
    a conditional import bound: ruff F821); ``MAX_IMPACTORS`` items pass."""
    if libyaml and loading._CParser is None:
        pytest.skip('PyYAML without libyaml')

    def text(n):
        if style == 'flow':
            return 'name: many\nimpactors: [' + ', '.join(['{}'] * n) + ']\n'
        return 'name: many\nimpactors:\n' + '- {}\n' * n

    def prescan(n):
        return loading._count_events(loading._events(text(n), libyaml), 'many.yaml', 'scene')

    prescan(MAX_IMPACTORS)   # the limit itself: no error
    with pytest.raises(SceneError) as info:
        prescan(MAX_IMPACTORS + 1)
    line = 2 if style == 'flow' else MAX_IMPACTORS + 3   # name, impactors:, then one a line
    assert str(info.value) == (
        f"many.yaml:{line}: scene key 'impactors': over the limit of 1,000 impactors (allowed "
        '0 to 1,000; impactor 1,001 is on this line): each costs time every step and memory '
        'in every stuck configuration; use fewer impactors')


def test_aliases_within_the_budget_still_load():
    data = load_yaml('a: &a {x: 1}\nb: *a\nc: [*a, *a]\n')
    assert data['b'] == {'x': 1} and data['c'] == [{'x': 1}, {'x': 1}]


@pytest.mark.parametrize('depth, ok', [(MAX_SCENE_DEPTH - 1, True), (1000, False)])
def test_nesting_depth(depth, ok):
    text = 'a: ' + '[' * depth + ']' * depth + '\n'
    if ok:
        assert load_yaml(text)['a'] is not None
    else:   # RecursionError before
        with pytest.raises(SceneError, match=f'nested deeper than {MAX_SCENE_DEPTH} levels'):
            load_yaml(text)


def test_a_recursive_alias_is_refused():
    with pytest.raises(SceneError, match='recursive alias'):
        load_yaml('a: &a [1, *a]\n')


def test_files_that_are_not_scene_files(tmp_path):
    big = tmp_path / 'big.yaml'
    big.write_text('# ' + 'x' * MAX_SCENE_BYTES + '\nname: s\n')
    binary = tmp_path / 'bin.yaml'
    binary.write_bytes(bytes(range(256)) + os.urandom(44))
    (tmp_path / 'dir.yaml').mkdir()
    fifo = tmp_path / 'fifo.yaml'
    os.mkfifo(fifo)
    zero = tmp_path / 'zero.yaml'
    zero.symlink_to('/dev/zero')
    cases = [(big, 'over 1048576 bytes'), (binary, 'not UTF-8 text'),
             (tmp_path / 'dir.yaml', 'not a regular file'), (fifo, 'not a regular file'),
             (zero, 'not a regular file'), (tmp_path / 'missing.yaml', 'does not exist')]
    for path, why in cases:
        with pytest.raises(SceneError, match=why):
            load(str(path))


@pytest.mark.parametrize('content, why', [
    (bytes(range(256)) + bytes(44), 'not UTF-8 text'),
    (BOMB.encode(), 'alias'),
    (('a: ' + '[' * 1000 + ']' * 1000 + '\n').encode(), 'nested deeper'),
])
def test_the_node_refuses_them_in_one_line_with_exit_2(tmp_path, content, why):
    """The node read these with tracebacks (UnicodeDecodeError, RecursionError) or hung."""
    pytest.importorskip('rclpy')
    path = tmp_path / 'g.yaml'
    path.write_bytes(content)
    lines, stderr = node_refusal(path, timeout=60)
    assert len(lines) == 1 and why in lines[0], stderr
    assert 'Traceback' not in stderr


def test_a_time_step_below_a_nanosecond_is_refused_in_one_line(capsys):
    """--dt 1e-308 overflowed the step count (OverflowError, exit 1) before."""
    from impact_damper_sim.cli.study import main
    for dt in ('1e-308', '5e-324'):
        assert main(['simulate', 'sdof', '--dt', dt]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and 'simulation.dt' in err[0] and '1e-09' in err[0], err


def test_a_plot_format_is_checked_before_the_work(capsys):
    """--plot r.txt failed in Matplotlib after the whole sweep, losing its table."""
    from impact_damper_sim.cli.study import PLOT_FORMATS, main
    t0 = time.process_time()
    assert main(['sweep', 'sdof', '--grid', 'impactors.0.clearance=1 mm,2 mm',
                 '--plot', 'x.txt']) == 2
    assert time.process_time() - t0 < 0.5   # refused before any simulation
    err = capsys.readouterr().err
    assert "--plot x.txt: cannot write a '.txt' plot" in err
    mpl = pytest.importorskip('matplotlib.pyplot')
    assert set(PLOT_FORMATS) <= set(mpl.figure().canvas.get_supported_filetypes())
