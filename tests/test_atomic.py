"""atomic_path: a file is replaced whole or not at all."""

import pytest

from activeperc_rl.atomic import atomic_path


def test_atomic_path_replaces_the_file_and_keeps_the_suffix(tmp_path):
    path = tmp_path / "sub" / "metrics.csv"
    with atomic_path(path) as temporary:
        assert temporary.parent == path.parent and temporary.suffix == ".csv" and temporary != path
        temporary.write_text("new")
        assert not path.exists()  # nothing at the destination until the block ends
    assert path.read_text() == "new"
    assert [p.name for p in path.parent.iterdir()] == ["metrics.csv"]


def test_atomic_path_leaves_the_old_file_when_the_writer_fails(tmp_path):
    path = tmp_path / "checkpoint.pt"
    path.write_text("old")
    with pytest.raises(KeyboardInterrupt), atomic_path(path) as temporary:
        temporary.write_text("half")
        raise KeyboardInterrupt
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["checkpoint.pt"]
