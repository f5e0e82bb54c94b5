"""docs/training.md stays true: its code examples run and its CLI tables match the parsers."""

import dataclasses
import re
from pathlib import Path

import pytest

from activeperc_env import EnvConfig
from activeperc_env.config import shown_default
from activeperc_rl import evaluate
from activeperc_rl.cli import build_parser, method_default
from activeperc_rl.recipe import METHOD_OPTIONS, SECTIONS

TRAINING_MD = Path(__file__).resolve().parents[1] / "docs" / "training.md"
TEXT = TRAINING_MD.read_text()
EXAMPLES = re.findall(r"```python\n(.*?)```", TEXT, flags=re.DOTALL)
ROW = re.compile(r"^\| `(-?-?[\w-]+)`(?:, `--no-[\w-]+`)? \| (`[^`]*`|[^|]*?) \|", flags=re.MULTILINE)


def section(title: str) -> str:
    """The text of the ``###`` section ``title`` (up to the next heading of any level)."""
    return TEXT.split(f"### {title}\n", 1)[1].split("\n#", 1)[0]


def table_rows(title: str) -> dict[str, str]:
    """``{first flag of a row: its default column}`` of the table in section ``title``."""
    return dict(ROW.findall(section(title)))


def config_defaults() -> dict[str, str]:
    """``{dest: default as typed}`` of every config field that is a flag (the sections', the methods' options and
    EnvConfig's): ``16 32`` for ``(16, 32)``, each room's for a field whose default is the room's own."""
    defaults = {}
    for cls in (*SECTIONS.values(), EnvConfig):
        for f in dataclasses.fields(cls):
            defaults[f.name] = shown_default(cls, f, as_flag=True)
    return defaults | {name: method_default(name) for name in METHOD_OPTIONS} | {"method": "meta"}


def test_training_md_has_examples():
    assert len(EXAMPLES) >= 3


@pytest.mark.parametrize("index", range(len(EXAMPLES)))
def test_training_md_example_runs(index):
    exec(compile(EXAMPLES[index], f"docs/training.md example {index}", "exec"), {"__name__": "__docs__"})


def test_train_table_lists_every_flag_with_its_default():
    rows = table_rows("`activeperc-train`")
    defaults = config_defaults()
    actions = [a for a in build_parser()._actions if a.option_strings and a.dest != "help"]
    from_fields = [a for a in actions if a.dest in defaults]
    assert {a.dest for a in from_fields} == set(defaults), "a config field has no activeperc-train flag"
    for action in actions:
        flag = action.option_strings[0]
        assert flag in rows, f"docs/training.md's activeperc-train table has no row for {flag}"
    for action in from_fields:
        flag, expected = action.option_strings[0], f"`{defaults[action.dest]}`"
        assert rows[flag] == expected, f"docs/training.md gives {flag} the default {rows[flag]}, not {expected}"
        assert f"(default: {defaults[action.dest]})" in action.help, f"{flag}'s --help shows another default"
    documented = set(rows) - {"--no-" + a.dest.replace("_", "-") for a in actions}
    assert documented <= {a.option_strings[0] for a in actions}, "the table lists flags the parser lacks"


def test_eval_table_matches_activeperc_eval_help(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")  # one line per option in the help text
    with pytest.raises(SystemExit):
        evaluate.main(["--help"])
    help_text = capsys.readouterr().out
    options = dict(re.findall(r"^  (--[\w-]+)[^\n]*?(?:\(default (\S+)\))?$", help_text, flags=re.MULTILINE))
    options.pop("--help", None)
    rows = table_rows("`activeperc-eval`")
    assert set(rows) - {"RUN"} == set(options), "docs/training.md's activeperc-eval table and --help differ"
    for flag, default in options.items():
        if default:
            assert rows[flag] == f"`{default}`", f"docs/training.md gives {flag} the default {rows[flag]}"
