"""How far one action carries the robot, cycle by cycle, from rest and amid random moves.

Run ``python experiments/motion_profile.py [--cycles 6] [--seed 0] [--random-cycles 1280] [--version 1]``: prints
the distance driven (m) and the heading change (degrees) of each of several consecutive identical
moves from rest, for every mover action, in the room of ``--version`` (the default room v1, or v0) with no
occluders; then the mean and standard deviation of the forward distance and heading change of each action when
every move is drawn uniformly at random (32 rooms, reset when the robot nears a wall), which shows how much of
the previous move's momentum a move keeps.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from activeperc_env import EnvConfig, Simulator, mover_actions, names
from activeperc_env.core import MOVER_ACTIONS
from activeperc_env.rooms import ROOMS


def profile(action: int, cycles: int, seed: int, version: int = 1) -> list[tuple[float, float]]:
    """(distance in m, heading change in degrees) of each of ``cycles`` repeats of ``action`` in room ``version``."""
    sim = Simulator(EnvConfig(num_obstacles=0, version=version), num_envs=1)
    sim.reset(seeds=[seed])
    steps = []
    for _ in range(cycles):
        xy, heading, _ = sim.pose()
        sim.move([action])
        new_xy, new_heading, _ = sim.pose()
        turn = math.atan2(math.sin(new_heading - heading), math.cos(new_heading - heading))
        steps.append((float(math.dist(xy, new_xy)), math.degrees(turn)))
    return steps


def random_moves(cycles: int, seed: int, num_envs: int = 32, version: int = 1) -> dict[int, np.ndarray]:
    """Per action, rows of (forward distance in m, heading change in degrees) under uniformly random moves."""
    sim = Simulator(EnvConfig(num_obstacles=0, max_cycles=10**6, version=version), num_envs=num_envs)
    rng = np.random.default_rng(seed)
    sim.reset(seeds=rng.integers(2**31, size=num_envs))
    rows: dict[int, list] = {a: [] for a in range(MOVER_ACTIONS)}
    for _ in range(cycles // num_envs):
        actions = rng.integers(MOVER_ACTIONS, size=num_envs)
        before = [sim.pose(i) for i in range(num_envs)]
        sim.move(actions)
        for i, (action, (xy, heading, _)) in enumerate(zip(actions, before, strict=True)):
            new_xy, new_heading, _ = sim.pose(i)
            forward = (new_xy[0] - xy[0]) * math.cos(heading) + (new_xy[1] - xy[1]) * math.sin(heading)
            turn = math.atan2(math.sin(new_heading - heading), math.cos(new_heading - heading))
            rows[int(action)].append((forward, math.degrees(turn)))
            if abs(new_xy[0]) > names.ROOM_HALF_X - 0.5 or abs(new_xy[1]) > names.ROOM_HALF_Y - 0.5:  # near a wall
                sim.reset([i], seeds=[int(rng.integers(2**31))])
    return {a: np.array(r) for a, r in rows.items()}


def main() -> None:
    """Print one row per action."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=6)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--random-cycles", type=int, default=1280)
    parser.add_argument("--version", type=int, choices=tuple(ROOMS), default=EnvConfig().version)
    args = parser.parse_args()
    if args.cycles < 1:
        parser.error(f"--cycles must be >= 1, got {args.cycles}")
    if args.random_cycles < 32:
        parser.error(f"--random-cycles must be >= 32 (one move in each of the 32 rooms), got {args.random_cycles}")
    for action, name in enumerate(mover_actions(args.version)):
        steps = profile(action, args.cycles, args.seed, args.version)
        print(f"{name:>10}  metres: " + " ".join(f"{d:.3f}" for d, _ in steps))
        print(f"{'':>10}  degrees: " + " ".join(f"{t:+.1f}" for _, t in steps))
    print(f"uniformly random moves ({args.random_cycles} cycles), mean +- std:")
    for action, rows in random_moves(args.random_cycles, args.seed, version=args.version).items():
        (dist, turn), (dist_sd, turn_sd) = rows.mean(axis=0), rows.std(axis=0)
        name = mover_actions(args.version)[action]
        print(f"{name:>10}  forward {dist:.3f} +- {dist_sd:.3f} m, turn {turn:+.1f} +- {turn_sd:.1f} degrees")


if __name__ == "__main__":
    main()
