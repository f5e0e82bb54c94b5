"""atomic_path: a file is replaced whole or not at all; check_writable: whether it could be written."""

import errno

import pytest

from activeperc_rl.runtime.atomic import atomic_path, check_writable


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


def test_atomic_path_gives_the_umask_permissions(tmp_path):
    import os
    import stat

    mask = os.umask(0o027)
    try:
        with atomic_path(tmp_path / "eval.json") as temporary:
            temporary.write_text("{}")
    finally:
        os.umask(mask)
    assert stat.S_IMODE((tmp_path / "eval.json").stat().st_mode) == 0o640  # not the temporary file's 0o600


def test_atomic_path_errors_name_the_file_asked_for(tmp_path):
    target = tmp_path / "video.mp4"
    with pytest.raises(OSError) as error, atomic_path(target) as temporary:
        raise OSError(errno.ENOSPC, "No space left on device", str(temporary))  # as a writer's would read
    assert error.value.filename == str(target) and error.value.errno == errno.ENOSPC
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(OSError) as error, atomic_path("/proc/video.mp4"):  # no file can be made there
        pass
    assert error.value.filename == "/proc/video.mp4"


def test_check_writable_tries_the_folder_rather_than_trusting_its_permissions(tmp_path):
    """Permissions say yes to root in /proc, where no file can be made: the check makes (and removes) one."""
    check_writable(tmp_path / "new" / "video.mp4")  # the folders are made when written
    assert list(tmp_path.iterdir()) == []  # the probe is gone
    with pytest.raises(ValueError, match=r"cannot write '/proc/v\.mp4': .* in '/proc'"):
        check_writable("/proc/v.mp4")  # root may write /proc by its permissions


def test_write_csv_writes_the_header_and_rows_with_newline_ends(tmp_path):
    from activeperc_rl.runtime.atomic import write_csv

    path = tmp_path / "results" / "rows.csv"
    write_csv(path, ["run", "success"], [{"run": "a", "success": 0.5}, {"run": "b, c", "success": 1}])
    assert path.read_bytes() == b'run,success\na,0.5\n"b, c",1\n'
