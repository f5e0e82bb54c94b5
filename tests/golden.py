"""Golden traces of the environment: digests of what seeded rooms give under fixed actions, through the core, the
PettingZoo parallel env and the TorchRL env, for every room version.

``python tests/golden.py`` writes ``tests/golden/traces.json``; ``tests/test_golden.py`` checks that this machine
gives the same. Write it again only for a change that is meant to change episodes (a new room version is a new
entry; v0's were written before v1 existed and must never change).
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

import activeperc_env
from activeperc_env import EnvConfig, Simulator

TRACES = Path(__file__).resolve().parent / "golden" / "traces.json"
SEEDS = (3, 17, 2024)
CYCLES = 40


def digest(*arrays) -> str:
    """The first 16 hex digits of the SHA-256 of the arrays' bytes."""
    h = hashlib.sha256()
    for array in arrays:
        h.update(np.ascontiguousarray(array).tobytes())
    return h.hexdigest()[:16]


def core_trace(version: int) -> dict[str, list[str]]:
    """Per FOV, one digest a cycle of three rooms under random moves and looks: both views, the physics state,
    rewards and ends (and the range readings, where the room has a range sensor)."""
    out = {}
    for fov in (60, 100):
        sim = Simulator(EnvConfig(fov=fov, version=version), num_envs=len(SEEDS), nthread=1)
        sim.reset(seeds=list(SEEDS))
        rng = np.random.default_rng(7)
        rows = []
        for _ in range(CYCLES):
            done = sim.done.copy()
            if done.any():
                sim.reset(np.flatnonzero(done))
            result = sim.move(rng.integers(3, size=len(SEEDS)))
            s_bar = sim.render()
            sim.look(rng.integers(3, size=len(SEEDS)))
            physics = sim.get_state()["physics"]
            parts = [s_bar, sim.render(), physics, result.reward, result.terminated, result.truncated]
            if sim.config.range_rays:
                parts.append(sim.ranges())
            rows.append(digest(*parts))
        out[f"fov{fov}"] = rows
        sim.close()
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


def main() -> None:
    """Write the traces of the versions named on the command line (all when none) into :data:`TRACES`."""
    versions = [int(v) for v in sys.argv[1:]] or list(activeperc_env.names.VERSIONS)
    stored = json.loads(TRACES.read_text()) if TRACES.exists() else {}
    for version in versions:
        stored[f"v{version}"] = traces(version)
    TRACES.parent.mkdir(exist_ok=True)
    TRACES.write_text(json.dumps(stored, indent=1) + "\n")
    print(f"wrote {TRACES} ({', '.join(sorted(stored))})")


if __name__ == "__main__":
    main()
