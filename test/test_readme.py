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

