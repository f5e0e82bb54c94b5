"""The console scripts ``activeperc-train`` and ``activeperc-eval``: a stop signal ends them cleanly from their first
moment, while torch and the rest still load (a second or more), not only once the command runs."""

from __future__ import annotations

import importlib
import sys

from activeperc_rl.runtime.signals import stop_raises_interrupt


def train() -> int:
    """``activeperc-train`` (:func:`activeperc_rl.cli.main`)."""
    return _started("activeperc-train", "activeperc_rl.cli")


def evaluate() -> int:
    """``activeperc-eval`` (:func:`activeperc_rl.evaluate.main`)."""
    return _started("activeperc-eval", "activeperc_rl.evaluate")


def _started(prog: str, module: str) -> int:
    """Import ``module`` and run its ``main()`` with SIGTERM and SIGHUP raising ``KeyboardInterrupt`` throughout (as
    Ctrl-C does); one that escapes ``main()`` (it came before the command started, or after it ended) is one line."""
    try:
        with stop_raises_interrupt():
            return importlib.import_module(module).main()
    except KeyboardInterrupt:
        print(f"\n{prog}: interrupted", file=sys.stderr)
        return 130
