"""The README stays true: its key table is the schema's and its API example runs."""
import re
from pathlib import Path

from impact_damper_sim.scene.schema import markdown_table
from impact_damper_sim.scene.spec import SCHEMA

README = Path(__file__).resolve().parents[1] / 'README.md'


def region(name):
    text = README.read_text()
    return text.split(f'<!-- {name}:start -->\n')[1].split(f'<!-- {name}:end -->')[0]


def test_key_table_is_the_schema():
    # regenerate with: .venv/bin/study keys --markdown
    text = region('scene-keys')
    table = markdown_table(SCHEMA)
    assert text.endswith('\n' + table), 'README key table differs from the schema'
    assert text.count('| Key | Type | Default | Range | Description |') == 1


def test_simulation_api_example_runs():
    code = re.search(r'```python\n(.*?)```', region('simulation-api'), flags=re.S).group(1)
    namespace = {}
    exec(compile(code, 'README.md', 'exec'), namespace)
    sim = namespace['sim']
    assert sim.t == 2.0 and namespace['acc'].shape == (10000, 1)


def test_simulation_api_example_runs(capsys):
    # The README's Simulation API example is executed as written, so it cannot rot.
    import re
    text = (Path(__file__).resolve().parents[1] / 'README.md').read_text()
    block = re.search(r'## Simulation API.*?```python\n(.*?)```', text, re.S)
    assert block, 'README has no Simulation API example'
    exec(compile(block.group(1), 'README.md', 'exec'), {})
    out = capsys.readouterr().out
    assert 'stuck' in out
