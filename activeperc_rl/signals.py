"""The signals that ask a run to stop, and the terminal that may be gone when one comes.

A run stops cleanly (it finishes its iteration and saves a checkpoint) on Ctrl-C (SIGINT), on SIGTERM (what
``kill``, ``docker stop``, systemd and batch schedulers send before they kill a job) and on SIGHUP, what a closing
terminal or a dropped SSH session sends, unless the process ignores SIGHUP (``nohup`` starts it so; it then goes
on ignoring it). After a SIGHUP the terminal is gone and writing to it fails, so whatever wrote to it must write
elsewhere before the run prints again: :class:`Terminal` remembers which standard streams wrote to a terminal
(known only before the hangup: a hung-up terminal no longer answers as one) and points them at ``/dev/null``.
"""

from __future__ import annotations

import os
import signal


def stop_signals() -> list[signal.Signals]:
    """SIGINT, SIGTERM and, unless this process ignores it, SIGHUP."""
    numbers = [signal.SIGINT, signal.SIGTERM]
    if signal.getsignal(signal.SIGHUP) is signal.SIG_DFL:
        numbers.append(signal.SIGHUP)
    return numbers


class Terminal:
    """Which of this process's stdout and stderr write to a terminal now, to point them at ``/dev/null`` when it
    hangs up."""

    def __init__(self):
        self.fds = [fd for fd in (1, 2) if _is_tty(fd)]

    def hung_up(self) -> None:
        """The terminal is gone: what was written to it goes to ``/dev/null`` from now on."""
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            for fd in self.fds:
                os.dup2(devnull, fd)
        finally:
            os.close(devnull)


def _is_tty(fd: int) -> bool:
    try:
        return os.isatty(fd)
    except OSError:
        return False
