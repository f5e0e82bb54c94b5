"""How far one action carries the robot, cycle by cycle, from rest.

Run ``python experiments/motion_profile.py [--cycles 6] [--seed 0]``: prints the distance driven
(m) and the heading change (degrees) of each of several consecutive identical moves from rest,
for every mover action, in the default room with no occluders.
"""

from __future__ import annotations

import argparse
import math

from activeperc_env import MOVER_ACTIONS, EnvConfig, Simulator


def profile(action: int, cycles: int, seed: int) -> list[tuple[float, float]]:
    """(distance in m, heading change in degrees) of each of ``cycles`` repeats of ``action``."""
    sim = Simulator(EnvConfig(num_obstacles=0), num_envs=1)
    sim.reset(seeds=[seed])
    steps = []
    for _ in range(cycles):
        xy, heading, _ = sim.pose()
        sim.move([action])
        new_xy, new_heading, _ = sim.pose()
        turn = math.atan2(math.sin(new_heading - heading), math.cos(new_heading - heading))
        steps.append((float(math.dist(xy, new_xy)), math.degrees(turn)))
    return steps


def main() -> None:
    """Print one row per action."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=6)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    for action, name in enumerate(MOVER_ACTIONS):
        steps = profile(action, args.cycles, args.seed)
        print(f"{name:>10}  metres: " + " ".join(f"{d:.3f}" for d, _ in steps))
        print(f"{'':>10}  degrees: " + " ".join(f"{t:+.1f}" for _, t in steps))


if __name__ == "__main__":
    main()
