"""What every speed benchmark shares: the timing loop, the machine's description, checked flags, and ratios of
rounds (each round of ours over the peer's figures around it)."""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import time
from collections.abc import Callable


def timed_rate(step: Callable[[], int], seconds: float, warmup: float) -> float:
    """Call ``step`` for ``warmup`` seconds untimed, then for ``seconds``; return units per second.

    ``step`` returns how many units (cycles or steps) one call did.
    """
    end = time.perf_counter() + warmup
    while time.perf_counter() < end:
        step()
    units = 0
    start = time.perf_counter()
    while True:
        units += step()
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            return units / elapsed


def machine_info() -> dict:
    """CPU count, platform and Python version of this machine."""
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "cpu_count": os.cpu_count(),
        "usable_cpus": usable,
        "processor": platform.processor() or platform.machine(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "mujoco_gl": os.environ.get("MUJOCO_GL", ""),
        "lp_num_threads": os.environ.get("LP_NUM_THREADS", "llvmpipe's default"),
    }


def at_least(kind: type, name: str, low: float, strict: bool = False) -> Callable[[str], int | float]:
    """An argparse ``type``: converts to ``kind`` and refuses values below ``low`` (or equal, if ``strict``), and
    infinity and NaN."""

    def convert(text: str) -> int | float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be {kind.__name__}, got {text!r}") from None
        if not math.isfinite(value) or value < low or (strict and value == low):
            raise argparse.ArgumentTypeError(f"{name} must be {'>' if strict else '>='} {low:g}, got {text}")
        return value

    return convert


def add_timing_flags(parser: argparse.ArgumentParser, seconds: float, warmup: float, per: str) -> None:
    """The flags every env benchmark takes, checked: ``--seconds`` timed per ``per`` (e.g. 'figure'), ``--rounds``
    with MiniWorld timed around each, ``--warmup`` before each timing and ``--seed``; the given defaults."""
    parser.add_argument(
        "--seconds",
        type=at_least(float, "seconds", 0, strict=True),
        default=seconds,
        help=f"timed seconds per {per} ({seconds:g})",
    )
    parser.add_argument(
        "--rounds", type=at_least(int, "rounds", 1), default=3, help=f"rounds of every {per}, MiniWorld around each (3)"
    )
    parser.add_argument(
        "--warmup",
        type=at_least(float, "warmup", 0),
        default=warmup,
        help=f"untimed seconds before each timing ({warmup:g})",
    )
    parser.add_argument(
        "--seed", type=at_least(int, "seed", 0), default=0, help="seed of the layouts and the random actions (0)"
    )
    parser.add_argument(
        "--peer-lp-threads",
        type=at_least(int, "peer-lp-threads", 0),
        help="LP_NUM_THREADS of MiniWorld's process (default: llvmpipe's own, as MiniWorld's users run it)",
    )


def bracketed_ratios(ours: list[float], peer: list[float]) -> list[float]:
    """Each round's figure of ours over the mean of the peer's figures just before and just after that round.

    ``peer`` holds one more figure than ``ours``: the peer was timed before the first round and after every round.
    """
    if len(peer) != len(ours) + 1:
        raise ValueError(f"{len(peer)} peer figures for {len(ours)} rounds: expected {len(ours) + 1}")
    return [mine / ((before + after) / 2) for mine, before, after in zip(ours, peer, peer[1:], strict=False)]


def rounds_met(ratios: list[float], multiple: float) -> str:
    """How often a goal of ``multiple`` was reached: ``"met in k of n rounds"``."""
    return f"met in {sum(ratio >= multiple for ratio in ratios)} of {len(ratios)} rounds"


def spread(values: list[float], digits: int, unit: str = "") -> str:
    """``"median (v1, v2, ...)"`` with ``digits`` decimals and ``unit`` after each number; the median alone for one
    value."""
    median = f"{statistics.median(values):.{digits}f}{unit}"
    if len(values) == 1:
        return median
    return f"{median} ({', '.join(f'{v:.{digits}f}{unit}' for v in values)})"
