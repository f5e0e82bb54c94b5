"""Golden traces: digests of what seeded rooms give under fixed actions, through the core, the PettingZoo parallel
env and the TorchRL env, for every room version; and of the first frames of training in portable mode.

``python tests/golden.py`` writes the environment's, ``tests/golden/traces.json`` (``python tests/golden.py 1``:
room v1's only), and ``python tests/golden.py training`` training's, ``tests/golden/training.json``;
``tests/test_golden.py`` checks that this machine gives the same. Write them again only for a change that is meant
to change episodes or training (a new room version is a new entry; v0's were written before v1 existed and must
never change).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

import activeperc_env
from activeperc_env import EnvConfig, Simulator
from activeperc_env.rooms import ROOMS
from activeperc_rl.runtime import portable

TRACES = Path(__file__).resolve().parent / "golden" / "traces.json"
TRAINING = TRACES.with_name("training.json")
TRAINING_RUNS = {
    # the runs of their day (2026-11): the pilot's recipe in room v1, the defaults then, with TorchRL's A2CLoss
    "meta": ("meta", ("--preset", "pilot", "--version", "1", "--no-reuse-features")),
    "fixed_forward": ("fixed_forward", ("--preset", "pilot", "--version", "1", "--no-reuse-features")),
    # today's defaults, the recipe that works in the default room
    "meta_default": ("meta", ()),
    "fixed_forward_default": ("fixed_forward", ()),
}
"""The golden training runs: their method and the flags they add to :data:`TRAINING_FLAGS`."""
TRAINING_METHODS = ("meta", "fixed_forward")  # the runs benchmarks/portable_bits.py trains and emulates
# a few iterations on seed 0, thread counts fixed (they may change rounding), no evaluation
TRAINING_FLAGS = ("--portable", "--frames", "3072", "--learner-threads", "2", "--torch-threads", "1")
TRAINING_FLAGS += ("--eval-episodes", "0", "--no-progress")
TRAINING_COLUMNS = ("frames", "iteration", "success_rate", "mean_return", "episodes")  # metrics.csv's, less timings
CONVOLUTIONS = {"onednn": (True, True), "nnpack": (False, True), "aten": (False, False)}
"""Which library runs torch's CPU convolutions: torch's switches of oneDNN and of NNPACK (NNPACK takes batches of 16
or more images where oneDNN is off; ATen's own im2col and MKL's matrix products take the rest)."""
# activeperc-train after setting torch's oneDNN and NNPACK switches, which no environment variable sets
PINNED_LAUNCHER = (
    "import sys, torch; torch.backends.mkldnn.enabled = {}; torch.backends.nnpack.set_flags({}); "
    "from activeperc_rl import cli; sys.exit(cli.main())"
)
SEEDS = (3, 17, 2024)
CYCLES = 40


def emulated(cpu: str | None, log: Path | None = None) -> list[str]:
    """The command prefix that runs a process under QEMU's emulated ``cpu`` (none for ``None``), writing to ``log``
    the code that QEMU translates, if given; ``ValueError`` where QEMU's user mode is not installed."""
    if cpu is None:
        return []
    if not shutil.which("qemu-x86_64"):
        raise ValueError(f"emulating {cpu} needs QEMU's user mode, qemu-x86_64 (apt install qemu-user)")
    return ["qemu-x86_64", "-cpu", cpu, *(["-d", "in_asm", "-D", str(log)] if log else [])]


def digest(*arrays) -> str:
    """The first 16 hex digits of the SHA-256 of the arrays' bytes."""
    h = hashlib.sha256()
    for array in arrays:
        h.update(np.ascontiguousarray(array).tobytes())
    return h.hexdigest()[:16]


def seeded_cycles(version: int, fov: int, cycles: int, rng_seed: int):
    """The rooms of :data:`SEEDS` under random moves and looks drawn from ``rng_seed``, a room reset when its
    episode ends: per cycle, the simulator, the move's result and the views before and after the look."""
    sim = Simulator(EnvConfig(fov=fov, version=version), num_envs=len(SEEDS), nthread=1)
    try:
        sim.reset(seeds=list(SEEDS))
        rng = np.random.default_rng(rng_seed)
        for _ in range(cycles):
            done = sim.done.copy()
            if done.any():
                sim.reset(np.flatnonzero(done))
            result = sim.move(rng.integers(3, size=len(SEEDS)))
            s_bar = sim.render()
            sim.look(rng.integers(3, size=len(SEEDS)))
            yield sim, result, s_bar, sim.render()
    finally:
        sim.close()


def core_trace(version: int) -> dict[str, list[str]]:
    """Per FOV, one digest a cycle of three rooms under random moves and looks: both views, the physics state,
    rewards and ends (and the range readings, where the room has a range sensor)."""
    out = {}
    for fov in (60, 100):
        rows = []
        for sim, result, s_bar, s in seeded_cycles(version, fov, CYCLES, rng_seed=7):
            physics = sim.get_state()["physics"]
            parts = [s_bar, s, physics, result.reward, result.terminated, result.truncated]
            if sim.config.range_rays:
                parts.append(sim.ranges())
            rows.append(digest(*parts))
        out[f"fov{fov}"] = rows
    return out


def parallel_env_trace(version: int) -> list[str]:
    """One digest a cycle of the PettingZoo parallel env's mover observation and rewards, three seeded episodes."""
    env = activeperc_env.parallel_env(version=version)
    rows = []
    for seed in SEEDS:
        env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        for _ in range(CYCLES):
            if not env.agents:
                break
            observations, rewards, *_ = env.step({agent: int(rng.integers(3)) for agent in env.agents})
            mover = observations["mover_0"]
            seen = [mover[key] for key in ("image", "pan", "range") if key in mover]
            rows.append(digest(*seen, np.array(list(rewards.values()))))
    env.close()
    return rows


def torchrl_trace(version: int) -> list[str]:
    """One digest a step of the TorchRL env (three rooms, external mode, auto-reset): the mover's observation,
    reward, done flags and the rooms' episode seeds."""
    import torch

    from activeperc_rl.envs import make_env

    env = make_env(num_envs=3, seed=5, nthread=1, version=version)
    td = env.reset()
    generator = torch.Generator().manual_seed(0)
    rows = []
    for _ in range(CYCLES):
        td.set(("mover", "action"), torch.randint(3, (3,), generator=generator))
        td.set(("looker", "action"), torch.randint(3, (3,), generator=generator))
        out, td = env.step_and_maybe_reset(td)
        step = out["next"]
        observation = step["mover", "observation"]
        seen = [observation[key].numpy() for key in ("image", "pan", "range") if key in observation.keys()]
        rows.append(digest(*seen, step["mover", "reward"].numpy(), step["done"].numpy(), env.episode_seeds))
    env.close()
    return rows


def traces(version: int) -> dict:
    """Every trace of room ``version``."""
    return {"core": core_trace(version), "parallel_env": parallel_env_trace(version), "torchrl": torchrl_trace(version)}


def train_portable(
    run: str,
    out: Path,
    pins: dict[str, str] | None = None,
    convolutions: str = "onednn",
    portable_flag: bool = False,
    emulate: str | None = None,
    emulate_log: Path | None = None,
) -> subprocess.CompletedProcess:
    """``activeperc-train --portable`` of the golden ``run`` (:data:`TRAINING_RUNS`) into ``out``, in a fresh process
    whose environment leaves torch's kernels unpinned, so that the command pins them itself; given ``pins``, another
    pinning to compare: the same run in a process started with those variables, its convolutions in the library
    ``convolutions`` names (:data:`CONVOLUTIONS`), and without ``--portable`` unless ``portable_flag`` (the flag also
    picks torch's fused Adam step). ``emulate`` (with ``pins``) runs it under ``qemu-x86_64 -cpu EMULATE``, which
    writes the code it translates to ``emulate_log`` if given."""
    if pins is None and (convolutions != "onednn" or portable_flag or emulate):
        raise ValueError("convolutions, portable_flag and emulate choose another pinning: give its pins too")
    if portable_flag and pins != portable.PINNED_ENVIRONMENT:
        raise ValueError(f"--portable would restart the run with {portable.PINNED_ENVIRONMENT}, not with {pins}")
    environment = {k: v for k, v in os.environ.items() if k not in portable.PINNED_ENVIRONMENT}
    method, recipe = TRAINING_RUNS[run]
    launcher, flags = ["-m", "activeperc_rl.cli"], [*TRAINING_FLAGS, *recipe]
    if pins is not None:
        environment |= pins
        launcher = ["-c", PINNED_LAUNCHER.format(*CONVOLUTIONS[convolutions])]
        if not portable_flag:
            flags.remove("--portable")
    # under emulation the process is pinned already: --portable starts no other (which would run unemulated)
    prefix = emulated(emulate, emulate_log)
    command = [*prefix, sys.executable, *launcher, "--method", method, *flags, "--out", str(out)]
    result = subprocess.run(command, env=environment, capture_output=True, text=True)
    if result.returncode:
        raise RuntimeError(f"{' '.join(command)} failed with status {result.returncode}:\n{result.stderr}")
    return result


def training_trace(out: Path) -> dict:
    """One digest a row of the run's ``metrics.csv`` in ``out`` (:data:`TRAINING_COLUMNS`) and one of the networks
    and optimizers it saved."""
    import csv

    import torch

    with open(out / "metrics.csv", newline="") as file:
        rows = [digest(np.array([row[key] for key in TRAINING_COLUMNS])) for row in csv.DictReader(file)]
    state = torch.load(out / "checkpoint.pt", map_location="cpu", weights_only=False)
    return {"metrics": rows, "weights": portable.state_digest(state["method"])}


def main() -> None:
    """Write the traces named on the command line: room versions (all when none) into :data:`TRACES`, or
    ``training`` into :data:`TRAINING`."""
    import tempfile

    if sys.argv[1:] == ["training"]:
        with tempfile.TemporaryDirectory() as folder:
            for run in TRAINING_RUNS:
                train_portable(run, Path(folder) / run)
            stored = {"pinned": portable.PINNED_ENVIRONMENT}
            stored |= {run: training_trace(Path(folder) / run) for run in TRAINING_RUNS}
        path = TRAINING
    else:
        versions = [int(v) for v in sys.argv[1:]] or list(ROOMS)
        stored = json.loads(TRACES.read_text()) if TRACES.exists() else {}
        for version in versions:
            stored[f"v{version}"] = traces(version)
        path = TRACES
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(stored, indent=1) + "\n")
    print(f"wrote {path} ({', '.join(sorted(stored))})")


if __name__ == "__main__":
    main()
