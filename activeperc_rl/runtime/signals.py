"""The signals that ask a run to stop, and the terminal that may be gone when one comes.

A run stops cleanly (it finishes its iteration and saves a checkpoint) on Ctrl-C (SIGINT), on SIGTERM (what
``kill``, ``docker stop``, systemd and batch schedulers send before they kill a job) and on SIGHUP, what a closing
terminal or a dropped SSH session sends, unless the process was started ignoring the signal, as ``nohup`` starts
it for SIGHUP and a shell without job control (a script's) starts a background job for SIGINT: it then goes on
ignoring it, as Python itself does with SIGINT.

After a SIGHUP the terminal is gone and writing to it fails, and so is any program the run wrote to through a
pipe from that terminal (``activeperc-train | tee train.log``: the terminal's SIGHUP stops ``tee`` too), so the
run must write elsewhere before it prints again: :class:`Terminal` remembers which standard
streams wrote to a terminal or a pipe (known only before the hangup: a hung-up terminal no longer answers as
one) and points them at ``/dev/null``.
"""

from __future__ import annotations

import os
import signal
import stat
import threading
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager


def stop_signals() -> list[signal.Signals]:
    """SIGINT, SIGTERM and SIGHUP, less those this process ignores: it was started so that they do not stop it
    (``nohup`` ignores SIGHUP; a shell without job control, as a script's, starts ``cmd &`` with SIGINT ignored, so
    that the terminal's Ctrl-C is not for it)."""
    numbers = [signal.SIGINT, signal.SIGTERM, signal.SIGHUP]
    return [number for number in numbers if signal.getsignal(number) is not signal.SIG_IGN]


class Terminal:
    """Which of this process's stdout and stderr write to a terminal or a pipe now, to point them at ``/dev/null``
    when the terminal hangs up (files stay as they are)."""

    def __init__(self):
        self.fds = [fd for fd in (1, 2) if _is_tty_or_pipe(fd)]

    def hung_up(self) -> None:
        """The terminal is gone: what was written to it, or to a pipe, goes to ``/dev/null`` from now on."""
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            for fd in self.fds:
                os.dup2(devnull, fd)
        finally:
            os.close(devnull)


def _is_tty_or_pipe(fd: int) -> bool:
    try:
        return os.isatty(fd) or stat.S_ISFIFO(os.fstat(fd).st_mode)
    except OSError:
        return False


@contextmanager
def on_stop_signals(action: Callable[[int], None], sigint: bool = True) -> Iterator[None]:
    """Within the block, each stop signal (:func:`stop_signals`, SIGINT only when ``sigint``) calls
    ``action(signum)``, after a SIGHUP has pointed what went to the terminal at ``/dev/null``. Off the main thread
    (where no handler can be set) the block runs with the signals as they are. The previous handlers are back
    when the block ends."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    terminal = Terminal()

    def handler(signum, frame):
        if signum == signal.SIGHUP:
            terminal.hung_up()
        action(signum)

    numbers = [number for number in stop_signals() if sigint or number != signal.SIGINT]
    previous = {number: signal.signal(number, handler) for number in numbers}
    try:
        yield
    finally:
        for number, handling in previous.items():
            signal.signal(number, handling)


def stop_raises_interrupt() -> AbstractContextManager[None]:
    """Within the block, SIGTERM and SIGHUP (when :func:`stop_signals` holds it) raise ``KeyboardInterrupt`` as
    Ctrl-C does, so that the caller's cleanup runs (temporary files removed, child processes stopped); after a
    SIGHUP what would go to the terminal goes to ``/dev/null`` (see :func:`on_stop_signals`)."""
    return on_stop_signals(_raise_interrupt, sigint=False)


def _raise_interrupt(signum: int) -> None:
    raise KeyboardInterrupt
