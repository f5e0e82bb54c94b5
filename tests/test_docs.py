"""docs/env.md stays true: its code examples run and its Arguments table matches ``EnvConfig``."""

import dataclasses
import re
import sys
import types
from pathlib import Path

import pytest

from activeperc_env import EnvConfig
from activeperc_env.config import shown_default

ENV_MD = Path(__file__).resolve().parents[1] / "docs" / "env.md"
TEXT = ENV_MD.read_text()


def examples(text: str) -> list[tuple[str, str]]:
    """(the heading of its section, the code) of each Python example in a Markdown text."""
    found, heading, fence, code = [], "", None, ""
    for line in text.splitlines(keepends=True):
        if fence is None and line.startswith("```"):
            fence, code = line.strip(), ""
        elif fence is not None and line.startswith("```"):
            if fence == "```python":
                found.append((heading, code))
            fence = None
        elif fence is not None:
            code += line
        elif line.startswith("#"):
            heading = line.lstrip("#").strip()
    return found


EXAMPLES = examples(TEXT)
OWN_VENV = ("benchmarl", "agilerl")
"""Libraries whose pins clash with the train extra's: .ci/run installs each beside the env alone and runs their examples
there (``-k NAME``)."""


def test_env_md_has_examples():
    assert len(EXAMPLES) >= 3


@pytest.mark.parametrize("code", [code for _, code in EXAMPLES], ids=[heading for heading, _ in EXAMPLES])
def test_env_md_example_runs(code, tmp_path, monkeypatch):
    for library in OWN_VENV:
        if re.search(rf"^(from|import) {library}\b", code, flags=re.MULTILINE):
            pytest.importorskip(library, reason=f"{library} runs in a venv of its own: .ci/run's {library} step")
    monkeypatch.chdir(tmp_path)  # what an example writes (BenchMARL's logs) stays out of the repository
    module = types.ModuleType("docs_example")  # a module pickle can find what the example defines in, as in a script
    monkeypatch.setitem(sys.modules, module.__name__, module)
    exec(compile(code, "docs/env.md example", "exec"), module.__dict__)


def test_arguments_table_lists_every_field_with_its_default():
    section = TEXT.split("## Arguments", 1)[1].split("\n## ", 1)[0]
    rows = dict(re.findall(r"^\| `(\w+)` \| `([^`]*)` \|", section, flags=re.MULTILINE))
    fields = {f.name: shown_default(EnvConfig, f).replace("'", '"') for f in dataclasses.fields(EnvConfig)}
    assert set(rows) == set(fields), "docs/env.md Arguments table and EnvConfig list different fields"
    for name, default in fields.items():
        assert rows[name] == default, f"docs/env.md gives {name}={rows[name]}, not {default}"
