"""Files written so that a kill at any moment leaves the previous version whole.

Each file a run or a benchmark writes whole (checkpoint, config, eval.json, results, plots, videos) is
written to a temporary file beside its destination, flushed to disk, and renamed over it. Two are not:
``metrics.csv`` is rewritten this way when a run starts or resumes and then takes one flushed row per
iteration (a kill mid-row leaves a torn last row, which a resume drops), and TensorBoard's event files are
TensorBoard's own.
"""

from __future__ import annotations

import csv
import glob
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` to write to; when the block ends, that file replaces ``path``.

    The temporary file keeps ``path``'s suffix (writers that pick a format from it still work), is
    flushed to disk before the rename, and is removed if the block raises, leaving ``path`` untouched.
    ``path``'s folder is created if needed. The file gets the permissions a plain ``open`` would give it
    (the umask's), not the owner-only ones of a temporary file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        handle, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix)
    except OSError as error:
        raise _naming(error, path) from error
    os.close(handle)
    temporary = Path(name)
    os.chmod(temporary, 0o666 & ~_umask())
    try:
        yield temporary
        with open(temporary, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(temporary, path)
    except BaseException as error:
        temporary.unlink(missing_ok=True)
        if isinstance(error, OSError) and error.errno and error.filename in (None, str(temporary)):  # a write: no name
            raise _naming(error, path) from error
        raise


def write_csv(path: str | Path, columns: list[str], rows) -> None:
    """Write the mappings ``rows`` under the header ``columns`` to the CSV file ``path`` (atomically, ``\n`` line
    ends)."""
    with atomic_path(path) as temporary, open(temporary, "w", newline="") as file:
        writer = csv.DictWriter(file, columns, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)


def _naming(error: OSError, path: Path) -> OSError:
    """``error`` as it would read for ``path``: the user asked for that file, not for our temporary one."""
    return type(error)(error.errno, error.strerror, str(path))


def check_writable(path: str | Path) -> None:
    """``ValueError`` naming ``path`` when :func:`atomic_path` could not write it: a directory stands there, a file
    stands where one of its folders should be, or no file can be made in the nearest existing folder (tried with
    a file made and removed again, as :func:`atomic_path` makes its own: permissions alone do not tell, e.g. for
    root in ``/sys``)."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{str(path)!r} is a directory, not a file")
    for folder in path.parents:  # the nearest first
        if folder.exists():
            if not folder.is_dir():
                raise ValueError(f"cannot write {str(path)!r}: {str(folder)!r} is a file, not a directory")
            try:
                handle, probe = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.probe.")
            except OSError as error:
                raise ValueError(f"cannot write {str(path)!r}: {error.strerror} in {str(folder)!r}") from None
            os.close(handle)
            os.unlink(probe)
            return


def _umask() -> int:
    """The process's umask (reading it means setting it: it is set straight back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def remove_leftovers(path: str | Path) -> list[Path]:
    """Remove the temporary files that :func:`atomic_path` left beside ``path`` when its process was killed.

    Only safe while no other process writes ``path`` (a run holds its directory's lock). Returns the
    removed files.
    """
    path = Path(path)
    leftovers = sorted(path.parent.glob(f".{glob.escape(path.name)}.*{glob.escape(path.suffix)}"))
    for leftover in leftovers:
        leftover.unlink(missing_ok=True)
    return leftovers
