"""What the benchmark scripts share: timing loops and part timers, the machine's description, checked flags, ratios
of rounds (each round of ours over the peer's figures around it), CSV output, and our rooms under random actions.

It imports nothing of ours at load time: MiniWorld's child process (``peer.py``) imports it too, and must not
import ``activeperc_env`` (which sets ``LP_NUM_THREADS`` for its process).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import functools
import math
import os
import platform
import statistics
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

# ------------------------------------------------------------------------------------------------------------- timing


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


SIMULATOR_PARTS = {  # the methods of activeperc_env.Simulator where a cycle's time goes, as the reports name them
    "move": "physics (Simulator.move)",
    "look": "look (Simulator.look)",
    "reset": "resets (Simulator.reset)",
    "render": "renders (Simulator.render)",
}
_ABSENT = object()


class Stopwatch:
    """Seconds spent in named parts of a run, added up by the calls it times (:meth:`timed`, :meth:`watching`); a
    timed call inside another counts in its own part only, not in the outer call's (unless that is ``whole``)."""

    def __init__(self):
        self.spent: dict[str, float] = {}
        self._inner: list[float] = []  # per timed call under way, the seconds of the timed calls inside it

    def restart(self) -> None:
        """Forget the time spent so far (in a warm-up, say); the parts stay."""
        self.spent = dict.fromkeys(self.spent, 0.0)

    def timed(self, part: str, function: Callable, whole: bool = False) -> Callable:
        """``function``, with the time of each call added to ``part``: less the timed calls inside it, or all of it
        with ``whole`` (a total around the other parts, which then count as if it were not timed)."""
        self.spent.setdefault(part, 0.0)

        @functools.wraps(function)
        def whole_call(*args, **kwargs):
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                self.spent[part] += time.perf_counter() - start

        @functools.wraps(function)
        def timed_call(*args, **kwargs):
            self._inner.append(0.0)
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                elapsed = time.perf_counter() - start
                self.spent[part] += elapsed - self._inner.pop()
                if self._inner:
                    self._inner[-1] += elapsed

        return whole_call if whole else timed_call

    @contextlib.contextmanager
    def watching(self, owner: object, names: Iterable[str]) -> Iterator[None]:
        """Within the block, time each method of ``owner`` (an object or a class) named in ``names`` as the part
        of its name; after it, ``owner`` is as it was."""
        kept = {name: vars(owner).get(name, _ABSENT) for name in names}
        for name in kept:
            setattr(owner, name, self.timed(name, getattr(owner, name)))
        try:
            yield
        finally:
            for name, method in kept.items():
                if method is _ABSENT:
                    delattr(owner, name)
                else:
                    setattr(owner, name, method)


def timed_parts(step: Callable[[], int], seconds: float, warmup: float, stopwatch: Stopwatch) -> tuple[float, dict]:
    """Time ``step`` as :func:`timed_rate` does while ``stopwatch`` times its parts; return the units per second and
    the seconds per unit spent in each part (the warm-up's time forgotten)."""
    units = 0

    def counted_step() -> int:
        nonlocal units
        done = step()
        units += done
        return done

    timed_rate(counted_step, warmup, 0.0)
    stopwatch.restart()
    units = 0
    rate = timed_rate(counted_step, seconds, 0.0)
    return rate, {part: spent / units for part, spent in stopwatch.spent.items()}


# ------------------------------------------------------------------------------------------------------------ machine


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


def machine_line(machine: dict) -> str:
    """The report's line on :func:`machine_info`'s CPUs, processor and GL backend."""
    cpus = f"{machine['usable_cpus']} usable CPUs ({machine['cpu_count']} total)"
    return f"machine: {cpus}, {machine['processor']}, MUJOCO_GL={machine['mujoco_gl'] or '(unset)'}"


# -------------------------------------------------------------------------------------------------------------- flags


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


def add_round_flags(parser: argparse.ArgumentParser, per: str) -> None:
    """The flags of the rounds, checked: ``--rounds`` of every ``per`` (e.g. 'figure') with MiniWorld timed around
    each, ``--no-peer`` and ``--peer-lp-threads``."""
    parser.add_argument(
        "--rounds", type=at_least(int, "rounds", 1), default=3, help=f"rounds of every {per}, MiniWorld around each (3)"
    )
    parser.add_argument("--no-peer", action="store_true", help="do not measure MiniWorld")
    parser.add_argument(
        "--peer-lp-threads",
        type=at_least(int, "peer-lp-threads", 0),
        help="LP_NUM_THREADS of MiniWorld's process (default: llvmpipe's own, as MiniWorld's users run it)",
    )


def add_timing_flags(parser: argparse.ArgumentParser, seconds: float, warmup: float, per: str) -> None:
    """The flags every env benchmark takes, checked: ``--seconds`` timed per ``per`` (e.g. 'figure'), ``--warmup``
    before each timing, ``--seed`` and the flags of :func:`add_round_flags`; the given defaults."""
    parser.add_argument(
        "--seconds",
        type=at_least(float, "seconds", 0, strict=True),
        default=seconds,
        help=f"timed seconds per {per} ({seconds:g})",
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
    add_round_flags(parser, per)


# ------------------------------------------------------------------------------------------------------------- rounds


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


def verdict(met: bool | None, ratios: list[float], multiple: float, cpus: int) -> str:
    """The report's word on a goal of ``multiple``, ``met`` or not (``None``: unknown) by the median of the rounds'
    ``ratios``: ``"MET (median; met in k of n rounds; 2 usable CPUs)"``, ``"NOT MET (...)"`` or ``"UNKNOWN"``."""
    if met is None:
        return "UNKNOWN"
    return f"{'MET' if met else 'NOT MET'} (median; {rounds_met(ratios, multiple)}; {cpus} usable CPUs)"


def spread(values: list[float], digits: int, unit: str = "") -> str:
    """``"median (v1, v2, ...)"`` with ``digits`` decimals and ``unit`` after each number; the median alone for one
    value."""
    median = f"{statistics.median(values):.{digits}f}{unit}"
    if len(values) == 1:
        return median
    return f"{median} ({', '.join(f'{v:.{digits}f}{unit}' for v in values)})"


def of_rounds(rounds: int) -> str:
    """What the report's figures are: ``"median of n rounds"``, or ``"one round"``."""
    return f"median of {rounds} rounds" if rounds > 1 else "one round"


# ------------------------------------------------------------------------------------------------------------- output


def refuse_unwritable(parser: argparse.ArgumentParser, outputs: dict[str, Path | None]) -> None:
    """Stop with the parser's error when a path of ``outputs`` ({flag: path or None}) could not be written: before
    minutes of timing, not after them."""
    from activeperc_rl.runtime.atomic import check_writable

    for flag, path in outputs.items():
        if path is not None:
            try:
                check_writable(path)
            except ValueError as error:
                parser.error(f"{flag}: {error}")


def write_csv(path: Path, header: tuple[str, ...], rows: list[tuple]) -> None:
    """Write ``rows`` under ``header`` to the CSV file ``path`` (atomically; ``None`` cells are left empty)."""
    from activeperc_rl.runtime.atomic import atomic_path

    with atomic_path(path) as temporary, open(temporary, "w", newline="") as out:
        writer = csv.writer(out)
        writer.writerow(header)
        writer.writerows(["" if cell is None else cell for cell in row] for row in rows)


# ---------------------------------------------------------------------------------------------------------- our rooms


def random_core(num_envs: int, seed: int, version: int = 1, backend: str = "mujoco", device: str = "cpu"):
    """A ``Simulator(num_envs)`` of room ``version`` on ``backend`` reset from ``seed`` with its first views rendered,
    and the rng of its actions."""
    import numpy as np

    import activeperc_env

    config = activeperc_env.EnvConfig(version=version)
    sim = activeperc_env.Simulator(config, num_envs=num_envs, backend=backend, device=device)
    sim.reset(seeds=seed + np.arange(num_envs))
    sim.render()
    return sim, np.random.default_rng(seed)


class RandomRooms:
    """A looker-mode ``make_env(num_envs)`` of room ``version`` stepped with random actions the way training's
    collectors step it (room v1 by default, as :func:`random_core`: the room the committed results were timed in)."""

    def __init__(self, num_envs: int, seed: int, backend: str = "mujoco", device: str = "cpu", version: int = 1):
        import torch

        from activeperc_rl import make_env
        from activeperc_rl.models import RandomPolicy

        torch.manual_seed(seed)
        looker = RandomPolicy(("looker",))
        self.env = make_env(num_envs, looker=looker, seed=seed, backend=backend, device=device, version=version)
        self.mover = RandomPolicy(("mover",))
        self.state = self.env.reset()

    def cycle(self) -> int:
        """Run one cycle in every room, restarting the finished ones; return how many episodes ended."""
        stepped, self.state = self.env.step_and_maybe_reset(self.mover(self.state))
        return int(stepped.get(("next", "done")).sum())

    def close(self) -> None:
        """Release the env's simulator."""
        self.env.close()


def core_cycle(sim, rng) -> None:
    """One random-action cycle of every room of ``sim``: move, render, look, render (the second render draws only
    the rooms whose camera turned), then reset and render the finished rooms."""
    import numpy as np

    sim.move(rng.integers(0, 3, sim.num_envs))
    sim.render()
    sim.look(rng.integers(0, 3, sim.num_envs))
    sim.render()
    done = np.flatnonzero(sim.done)
    if done.size:
        sim.reset(done)
        sim.render(done)


def timed_core(sim, rng, seconds: float, warmup: float) -> tuple[float, dict[str, float]]:
    """Time :func:`core_cycle` on ``sim`` as :func:`timed_parts` does: whole cycles per second (not summed over the
    rooms) and the seconds per cycle spent in each method of :data:`SIMULATOR_PARTS`."""
    stopwatch = Stopwatch()

    def cycle() -> int:
        core_cycle(sim, rng)
        return 1

    with stopwatch.watching(sim, SIMULATOR_PARTS):
        return timed_parts(cycle, seconds, warmup, stopwatch)
