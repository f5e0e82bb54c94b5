"""docs/tables.py: every generated table in docs/ and README.md is what its committed CSV gives, and a table edited
by hand is caught."""

import importlib.util
import re
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SPEC = importlib.util.spec_from_file_location("tables", ROOT / "docs" / "tables.py")
tables = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(tables)


def copied_docs(tmp_path: Path) -> Path:
    """A copy of docs/*.md in ``tmp_path/docs``, with README.md beside it (where the README's tables are)."""
    docs = tmp_path / "docs"
    docs.mkdir()
    for doc in (ROOT / "docs").glob("*.md"):
        shutil.copy(doc, docs)
    shutil.copy(ROOT / "README.md", tmp_path)
    return docs


def test_generated_tables_are_up_to_date():
    assert tables.stale() == [], "run python docs/tables.py"


@pytest.mark.parametrize("marker", sorted(tables.SECTIONS))
def test_a_number_edited_by_hand_is_caught(marker, tmp_path):
    docs = copied_docs(tmp_path)
    path = docs / tables.SECTIONS[marker][0]
    text = path.read_text()
    start = text.index(f"<!-- {marker} -->\n") + len(f"<!-- {marker} -->\n")
    digit = re.compile(r"\d").search(text, start)
    assert digit and digit.start() < text.index(f"<!-- /{marker} -->"), f"the table '{marker}' holds no number"
    edited = str((int(digit.group()) + 1) % 10)
    path.write_text(text[: digit.start()] + edited + text[digit.end() :])
    assert tables.stale(docs) == [marker]


def test_a_document_without_its_markers_is_named(tmp_path):
    docs = copied_docs(tmp_path)
    (docs / "training.md").write_text("no tables here\n")
    with pytest.raises(ValueError, match="training.md"):
        tables.stale(docs)
