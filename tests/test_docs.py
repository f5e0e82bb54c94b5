"""docs/env.md stays true: its code examples run and its Arguments table matches ``EnvConfig``."""

import dataclasses
import re
from pathlib import Path

import pytest

from activeperc_env import EnvConfig
from activeperc_env.config import shown_default

ENV_MD = Path(__file__).resolve().parents[1] / "docs" / "env.md"
TEXT = ENV_MD.read_text()
EXAMPLES = re.findall(r"```python\n(.*?)```", TEXT, flags=re.DOTALL)


def test_env_md_has_examples():
    assert len(EXAMPLES) >= 3


@pytest.mark.parametrize("index", range(len(EXAMPLES)))
def test_env_md_example_runs(index):
    exec(compile(EXAMPLES[index], f"docs/env.md example {index}", "exec"), {"__name__": "__docs__"})


def test_arguments_table_lists_every_field_with_its_default():
    section = TEXT.split("## Arguments", 1)[1].split("\n## ", 1)[0]
    rows = dict(re.findall(r"^\| `(\w+)` \| `([^`]*)` \|", section, flags=re.MULTILINE))
    fields = {f.name: shown_default(EnvConfig, f).replace("'", '"') for f in dataclasses.fields(EnvConfig)}
    assert set(rows) == set(fields), "docs/env.md Arguments table and EnvConfig list different fields"
    for name, default in fields.items():
        assert rows[name] == default, f"docs/env.md gives {name}={rows[name]}, not {default}"
