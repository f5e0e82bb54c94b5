"""MiniWorld, the peer of our speed benchmarks: timed in a child process, on request, between our own measurements.

The machine's speed drifts from minute to minute (other work on the host), and MiniWorld drifts with it, so a
ratio of two figures taken a minute apart says more about the drift than about us. The benchmarks therefore
time in rounds: MiniWorld, then a round of ours, then MiniWorld again, and so on, and divide each round of ours
by the mean of the two MiniWorld figures around it (:func:`harness.bracketed_ratios`). :class:`MiniWorld` keeps one
MiniWorld env alive in a child process for that, so each of its measurements costs only its own seconds; a GL
failure in the child cannot stop our measurements, it becomes a :class:`PeerUnavailable` that says why.

MiniWorld comes with the project's ``bench`` extra (``pip install -e .[bench]`` or ``pip install miniworld==2.1.0``).
"""

from __future__ import annotations

import argparse
import json
import os
import queue
import statistics
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

PEER_ENV = "MiniWorld-OneRoom-v0"
OBS_WIDTH, OBS_HEIGHT = 80, 60
TAG = "MINIWORLD_RESULT "  # prefix of the child's answer lines; anything else it prints is ignored
START_TIMEOUT = 300.0  # seconds the child may take to build its env
ANSWER_MARGIN = 120.0  # seconds a measurement may overrun its requested time


class PeerUnavailable(RuntimeError):
    """MiniWorld could not be measured; the message says why."""


class MiniWorld:
    """``MiniWorld-OneRoom-v0`` at 80x60 in a child process, its raw random-action steps/s timed on request.

    Args:
        seed: seed of the env's reset and of its random actions.
        lp_threads: ``LP_NUM_THREADS`` of the child (Mesa's llvmpipe threads; 0: it draws in the calling thread).
            ``None``: as its users run it, llvmpipe's default, unless this process was started with the variable
            set (``import activeperc_env`` sets it to 0 for us when it is unset; MiniWorld does not).

    ``info`` holds the child's ``version``, ``obs_shape``, ``gl_renderer`` and ``lp_num_threads``. Use it as a
    context manager, or call :meth:`close`. Raises :class:`PeerUnavailable` when the child cannot start or answer.
    """

    def __init__(self, seed: int = 0, lp_threads: int | None = None):
        from activeperc_env import gl

        environment = dict(os.environ)
        if lp_threads is not None:
            environment["LP_NUM_THREADS"] = str(lp_threads)
        elif gl.LLVMPIPE_THREADS_CHOSEN:
            environment.pop("LP_NUM_THREADS", None)
        self._stderr = tempfile.TemporaryFile(mode="w+")
        command = [sys.executable, os.path.abspath(__file__), "--serve", "--seed", str(seed)]
        self._proc = subprocess.Popen(
            command,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self._stderr,
            text=True,
            bufsize=1,
            env=environment,
        )
        self._answers: queue.Queue[str | None] = queue.Queue()
        threading.Thread(target=self._read_answers, daemon=True).start()
        try:
            self.info = self._answer(START_TIMEOUT)
        except PeerUnavailable:
            self.close()
            raise

    def measure(self, seconds: float, warmup: float) -> float:
        """MiniWorld's raw ``env.step`` calls per second over ``seconds``, after ``warmup`` untimed seconds
        (one render each; the env is reset when an episode ends)."""
        try:
            self._proc.stdin.write(f"{seconds} {warmup}\n")
            self._proc.stdin.flush()
        except (BrokenPipeError, OSError, ValueError):
            raise PeerUnavailable(self._why_gone()) from None
        return self._answer(seconds + warmup + ANSWER_MARGIN)["steps_per_s"]

    def close(self) -> None:
        """End the child process."""
        if self._proc.poll() is None:
            try:
                self._proc.stdin.close()
                self._proc.wait(timeout=30)
            except (OSError, subprocess.TimeoutExpired):
                self._proc.kill()
                self._proc.wait()
        self._stderr.close()

    def __enter__(self) -> MiniWorld:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _read_answers(self) -> None:
        """Reader thread: put each tagged line of the child's stdout on the queue, then ``None`` at its end."""
        for line in self._proc.stdout:
            if line.startswith(TAG):
                self._answers.put(line[len(TAG) :])
        self._answers.put(None)

    def _answer(self, timeout: float) -> dict:
        try:
            line = self._answers.get(timeout=timeout)
        except queue.Empty:
            self._proc.kill()
            raise PeerUnavailable(f"the MiniWorld process did not answer within {timeout:g} s") from None
        if line is None:
            raise PeerUnavailable(self._why_gone())
        return json.loads(line)

    def _why_gone(self) -> str:
        """Why the child stopped answering: its exit status and the last lines it wrote to stderr."""
        status = self._proc.wait()
        self._stderr.seek(0)
        tail = [line.strip() for line in self._stderr.read().strip().splitlines()[-3:]]
        why = f"the MiniWorld process exited with status {status}"
        if any(f"No module named '{module}'" in line for line in tail for module in ("miniworld", "pyglet")):
            why += " (miniworld is not installed: pip install miniworld==2.1.0, the project's bench extra)"
        return why + (": " + " | ".join(tail) if tail else "")


@dataclass
class Rounds:
    """What :func:`in_rounds` measured: ours per round, and MiniWorld around the rounds."""

    ours: list = field(default_factory=list)
    """What each round of ours returned."""
    peer: list[float] | None = field(default_factory=list)
    """MiniWorld's steps/s before the first round and after each (``len(ours) + 1``); ``None`` if it failed."""
    info: dict | None = None
    """MiniWorld's ``version``, ``obs_shape`` and ``gl_renderer``."""
    why: str | None = None
    """Why MiniWorld was not measured, when it was not."""

    def report(self) -> dict:
        """MiniWorld's part of a benchmark's JSON report."""
        return {"miniworld": self.info, "miniworld_steps_per_s": self.peer, "miniworld_error": self.why}


def in_rounds(
    rounds: int,
    measure_round: Callable[[int], object],
    seconds: float,
    warmup: float,
    seed: int,
    lp_threads: int | None = None,
    skip: bool = False,
) -> Rounds:
    """Call ``measure_round(i)`` for ``i`` in ``range(rounds)``, with MiniWorld (``LP_NUM_THREADS=lp_threads``, as
    :class:`MiniWorld` takes it) timed for ``seconds`` (after ``warmup``) before the first round and after each; each
    MiniWorld figure is printed as it comes.

    When MiniWorld is skipped (``skip``, the flag ``--no-peer``), cannot start or stops answering, our rounds go on
    and the result says why.
    """
    result, miniworld = Rounds(), None
    if skip:
        result.peer, result.why = None, "skipped (--no-peer)"
    else:
        try:
            miniworld = MiniWorld(seed, lp_threads)
            result.info = miniworld.info
        except PeerUnavailable as error:
            result.peer, result.why = None, str(error)

    def time_peer() -> None:
        nonlocal miniworld
        if miniworld is None:
            return
        try:
            result.peer.append(miniworld.measure(seconds, warmup))
            print(f"      MiniWorld {result.peer[-1]:.1f} steps/s", flush=True)
        except PeerUnavailable as error:
            miniworld.close()
            miniworld, result.peer, result.why = None, None, str(error)

    try:
        time_peer()
        for i in range(rounds):
            result.ours.append(measure_round(i))
            time_peer()
    finally:
        if miniworld is not None:
            miniworld.close()
    return result


def describe(measured: Rounds, width: int = 34) -> str:
    """The report's line on MiniWorld: the median of its figures and each of them, or why it was not measured."""
    if not measured.peer:
        return f"peer  MiniWorld {PEER_ENV}: NOT MEASURED, {measured.why}"
    info = measured.info
    label = f"MiniWorld {info['version']} {PEER_ENV}"
    shape = "x".join(map(str, info["obs_shape"]))
    every = ", ".join(f"{rate:.1f}" for rate in measured.peer)
    return (
        f"peer  {label:<{width}}{statistics.median(measured.peer):9.1f} steps/s    (median of {every}; raw env.step,"
        f" obs {shape}, GL: {info['gl_renderer']}, LP_NUM_THREADS: {info.get('lp_num_threads', '?')})"
    )


def serve(seed: int) -> None:
    """Child side: build the env, announce it, then time it for each ``"seconds warmup"`` line read from stdin."""
    import pyglet

    pyglet.options["headless"] = True  # before miniworld imports pyglet's GL
    import gymnasium
    import miniworld
    from harness import timed_rate  # the same timing loop as ours; harness.py sits next to this file

    env = gymnasium.make(PEER_ENV, obs_width=OBS_WIDTH, obs_height=OBS_HEIGHT)
    obs, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    try:
        gl_renderer = pyglet.gl.gl_info.get_renderer()
    except Exception:  # only informative
        gl_renderer = "?"
    threads = os.environ.get("LP_NUM_THREADS", "llvmpipe's default")
    info = {
        "version": miniworld.__version__,
        "obs_shape": list(obs.shape),
        "gl_renderer": gl_renderer,
        "lp_num_threads": threads,
    }
    print(TAG + json.dumps(info), flush=True)

    def step() -> int:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            env.reset()
        return 1

    for request in sys.stdin:
        seconds, warmup = map(float, request.split())
        print(TAG + json.dumps({"steps_per_s": timed_rate(step, seconds, warmup)}), flush=True)
    env.close()


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="child process of MiniWorld (started by the benchmarks)")
    parser.add_argument("--serve", action="store_true", required=True)
    parser.add_argument("--seed", type=int, default=0)
    serve(parser.parse_args().seed)
