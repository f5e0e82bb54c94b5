"""The run directory's guards: one training process at a time, and no run overwritten by a fresh one.

:func:`claim_run_dir` holds an advisory lock (``flock`` on ``RUN_DIR/.lock``) for as long as a
process trains into the directory: a second ``activeperc-train`` with the same ``--out`` is refused
instead of interleaving its rows and checkpoints with the first one's. The kernel drops the lock
when its process dies, however it dies, so a killed run never leaves the directory locked. Holding
the lock, the process also removes the temporary files that a killed writer left behind
(:func:`~activeperc_rl.runtime.atomic.remove_leftovers`).
"""

from __future__ import annotations

import fcntl
import itertools
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from activeperc_rl.runtime.atomic import remove_leftovers
from activeperc_rl.runtime.checkpoint import CHECKPOINT, CONFIG, EVAL, METRICS

LOCK = ".lock"
RUN_FILES = (CHECKPOINT, CONFIG, METRICS, EVAL)
"""The files a run writes; a fresh run starts only in a directory that holds none of them."""


@contextmanager
def claim_run_dir(out: str | Path) -> Iterator[Path]:
    """Create ``out`` if needed and hold its lock for the block; ``ValueError`` when another process holds it.

    A directory that this call created and that holds nothing but the lock when the block ends (the run failed
    before writing anything) is removed again.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {str(out)!r} is a file, not a directory")
    while True:
        try:
            out.mkdir(parents=True)
            created = True
        except FileExistsError:
            created = False
        try:
            fd = os.open(out / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
        except FileNotFoundError:  # the directory was removed since (by a run that failed before writing): again
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 32).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            raise ValueError(
                f"{str(out)!r} is in use by another training process (pid {holder}): wait for it to end, "
                f"or choose another --out"
            ) from None
        if _is_the_lock_file(fd, out / LOCK):
            break
        os.close(fd)  # we locked a lock file that its holder removed (with its unused directory) meanwhile: again
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        for name in RUN_FILES:
            remove_leftovers(out / name)
        yield out
    finally:
        if created:
            remove_if_unused(out)
        os.close(fd)


def _is_the_lock_file(fd: int, path: Path) -> bool:
    """Whether the open file ``fd`` is still the file at ``path`` (not one removed after we opened it)."""
    try:
        return os.path.samestat(os.fstat(fd), os.stat(path))
    except FileNotFoundError:
        return False


def new_run_dir(stem: str | Path) -> Path:
    """Create and return the first of ``stem``, ``stem-2``, ``stem-3``, ... that does not exist yet.

    Each name is taken by an atomic ``mkdir``, so runs started at the same moment get different directories.
    """
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    for n in itertools.count(1):
        path = stem if n == 1 else stem.with_name(f"{stem.name}-{n}")
        try:
            path.mkdir()
            return path
        except FileExistsError:
            continue


def remove_if_unused(out: str | Path) -> None:
    """Remove the directory ``out`` if it holds nothing but a run's lock file (nothing of a run was written)."""
    out = Path(out)
    if out.is_dir() and {p.name for p in out.iterdir()} <= {LOCK}:
        (out / LOCK).unlink(missing_ok=True)
        out.rmdir()


def run_files(out: str | Path) -> list[str]:
    """The names of :data:`RUN_FILES` that ``out`` holds."""
    return [name for name in RUN_FILES if (Path(out) / name).exists()]


def check_fresh(out: str | Path) -> None:
    """``ValueError`` when ``out`` holds files of a run, which a fresh run would overwrite."""
    found = run_files(out)
    if CHECKPOINT in found:
        raise ValueError(
            f"{str(out)!r} already holds a run ({', '.join(found)}): pass --resume to continue it, "
            "or choose another --out"
        )
    if found:
        raise ValueError(
            f"{str(out)!r} holds {', '.join(found)} of an earlier run but no {CHECKPOINT} to resume from: "
            f"move them away, or choose another --out"
        )
