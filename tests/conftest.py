"""Shared helpers for the test suite."""

import fcntl
import math
import os
import pty
import select
import signal
import struct
import subprocess
import termios
import time

import numpy as np


def share_the_cpus_among_workers() -> None:
    """Under pytest-xdist (``-n``), keep each worker and the processes it starts on its own share of the CPUs: torch
    threads of two workers on the same cores wait on each other (a training that takes 6 s alone took 140 s)."""
    worker, count = os.environ.get("PYTEST_XDIST_WORKER"), os.environ.get("PYTEST_XDIST_WORKER_COUNT")
    if worker and count and hasattr(os, "sched_setaffinity"):
        cpus = sorted(os.sched_getaffinity(0))
        if int(count) <= len(cpus):
            os.sched_setaffinity(0, cpus[int(worker.removeprefix("gw")) :: int(count)])


share_the_cpus_among_workers()  # before torch starts its threads

import activeperc_env  # noqa: E402, F401  (chooses the headless GL backend before mujoco renders)

EASY_ROOM = dict(
    num_obstacles=0, goal_distance=2.5, heading_spread=0.0, forward_speed=3.0, control_hz=2.5, max_cycles=10
)
"""An empty room where the goal lies straight ahead, two forward moves away: random moves reach it often (the other
RL libraries' tests train there)."""


def goal_seeking_move(sim, index: int = 0) -> int:
    """A scripted mover that knows where the goal is: turn towards it, then drive forward."""
    xy, heading, _ = sim.pose(index)
    to_goal = sim.goal_xy(index) - xy
    error = math.atan2(to_goal[1], to_goal[0]) - heading
    error = math.atan2(math.sin(error), math.cos(error))
    if abs(error) < math.radians(12):
        return 2
    return 0 if error > 0 else 1


def drive_to_goal(sim, index: int = 0, max_cycles: int = 200):
    """Run the scripted mover in room ``index``; the (cycle, reward) pairs until the episode ends."""
    rewards = []
    for _ in range(max_cycles):
        result = sim.move(np.array([goal_seeking_move(sim, index)]), ids=[index])
        rewards.append((int(sim.cycle[index]), float(result.reward[0])))
        if result.terminated[0] or result.truncated[0]:
            break
    return rewards


def assert_same_run(run_a, run_b, columns=("frames", "iteration", "success_rate", "mean_return", "episodes")):
    """Two training runs logged the same ``metrics.csv`` rows in ``columns`` and ended with the same networks
    (tensor by tensor); returns the rows."""
    import csv

    import torch

    from activeperc_rl.runtime.checkpoint import load_checkpoint

    rows = []
    for run in (run_a, run_b):
        with open(run / "metrics.csv", newline="") as f:
            rows.append([{k: r[k] for k in columns} for r in csv.DictReader(f)])
    assert rows[0] == rows[1]
    sa, sb = (load_checkpoint(run / "checkpoint.pt")["method"]["modules"] for run in (run_a, run_b))
    for name in sa:
        for key, value in sa[name].items():
            assert torch.equal(value, sb[name][key]), (name, key)
    return rows[0]


def assert_same_view(a, b):
    """Views of the same state, equal up to the rasteriser's rounding: drawn at another offset of the framebuffer, a
    view may differ in pixels' shades by one level (in up to 61 % of its pixels), and in at most one pixel by more
    (an edge pixel with the colour of the surface beside it), as ``experiments/tile_shading.py`` measured; a view of
    another state or camera differs far more. ``a`` and ``b``: one view (h, w, 3) or equal stacks of them."""
    assert a.shape == b.shape and a.dtype == b.dtype == np.uint8
    beyond_one_level = (np.abs(a.astype(int) - b.astype(int)).max(axis=-1) > 1).sum(axis=(-2, -1))
    assert beyond_one_level.max() <= 2, f"pixels differing by more than one level: {beyond_one_level}"


def default_stop_signals() -> None:
    """SIGINT and SIGHUP at their defaults in a child process (a ``preexec_fn``), also when the tests run under
    ``nohup`` or as a background job of a shell without job control (which ignore them, and a child inherits that)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGHUP, signal.SIG_DFL)


class PseudoTerminal:
    """A terminal (a pty, 24 rows of 100 columns) for a child process's stdout and stderr, which the test reads
    (so that the child never blocks on a full terminal) and can hang up, as a closing terminal window or a
    dropped SSH session does: from then on the child's writes to it fail."""

    def __init__(self):
        self.master, self._child_side = pty.openpty()
        fcntl.ioctl(self._child_side, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
        self.seen = bytearray()

    def start(self, command: list[str]) -> subprocess.Popen:
        """Start ``command`` writing to this terminal, with SIGHUP at its default (also when the tests run under
        ``nohup``)."""
        process = subprocess.Popen(
            command,
            stdin=subprocess.DEVNULL,
            stdout=self._child_side,
            stderr=self._child_side,
            start_new_session=True,
            preexec_fn=default_stop_signals,
        )
        os.close(self._child_side)
        return process

    def read_until(self, done, timeout: float = 120) -> None:
        """Read what the child writes until ``done()`` is true or ``timeout`` seconds have passed."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not done():
            if select.select([self.master], [], [], 0.2)[0]:
                self.seen += os.read(self.master, 65536)

    def hang_up(self) -> None:
        """Close the terminal: the child's writes to it fail from now on."""
        os.close(self.master)
