"""What a run's mover critic says each look is worth, and what its looker does with it.

Run from the repository root::

    python experiments/look_values.py runs/meta-seed0-TIME
    python experiments/look_values.py RUN --cycles 150 --rooms 16 --epsilon 0.3 --csv look_values.csv

The run's mover plays ``--rooms`` held-out rooms for ``--cycles`` cycles with a looker that holds the camera, or
takes a uniformly random look with probability ``--epsilon`` (E2's exploration around a looker that holds). In
every cycle the views of all three looks are drawn (``make_env(look_views=True)``) and the mover's critic values
each: ``Q(u) = V(s'(u))``. The looks are grouped by where the goal is in the looker's view ``s_bar`` (not in view,
in the left or right third, in the middle third), and for each group the script prints how many looks it holds,
the mean of ``Q(pan left) - Q(hold)`` and ``Q(pan right) - Q(hold)``, how often each pan is the best look, and how
often the run's ``phi2`` (``meta``) picks each look greedily, with its mean probability of each. A critic that values
looking says: pan where the goal is out of view or off centre, hold where it is centred. ``--csv`` adds the groups'
rows to a CSV (replacing the run's rows).
"""

from __future__ import annotations

import datetime
import math
import sys
from pathlib import Path

import numpy as np
import torch
from pan_vs_bearing import write_rows
from tensordict import TensorDict
from torch import nn
from torchrl.envs.utils import ExplorationType, set_exploration_type

from activeperc_env.arguments import ArgumentParser, whole_number
from activeperc_env.core import HOLD, LOOKER_ACTIONS
from activeperc_env.scripted import goal_in_view
from activeperc_rl.envs import LOOKER, MOVER, latest_view, make_env
from activeperc_rl.recipe import make_method
from activeperc_rl.runtime import portable
from activeperc_rl.runtime.checkpoint import CHECKPOINT, load_checkpoint, load_run_config, restore_method

GROUPS = ("not in view", "left third", "middle third", "right third")
COLUMNS = [
    "run", "goal_in_s_bar", "looks", "gain_left", "gain_right", "best_left", "best_right", "greedy_left", "greedy_hold",
    "greedy_right", "p_left", "p_hold", "p_right", "machine", "date",
]  # fmt: skip


class HoldOrExplore(nn.Module):
    """Holds the camera, or with probability ``epsilon`` takes a uniformly random look."""

    def __init__(self, epsilon: float):
        super().__init__()
        self.epsilon = epsilon

    def forward(self, tensordict):
        """Write the looks into ``tensordict``."""
        shape = tensordict.batch_size
        explore = torch.rand(shape) < self.epsilon
        tensordict.set((LOOKER, "action"), torch.where(explore, torch.randint(len(LOOKER_ACTIONS), shape), HOLD))
        return tensordict


def look_values(critic, record: TensorDict) -> torch.Tensor:
    """``(n, 3)``: the critic's value of the view of each look of the looker's ``record`` (its ``look_views``, with the
    range readings of ``s_bar``)."""
    values = []
    for look in range(len(LOOKER_ACTIONS)):
        views = {
            (MOVER, "observation", "image"): record["look_views", "image"][:, look],
            (MOVER, "observation", "pan"): record["look_views", "pan"][:, look],
        }
        if ("observation", "range") in record.keys(True):
            views[(MOVER, "observation", "range")] = record["observation", "range"]
        with torch.no_grad():
            values.append(critic(TensorDict(views, batch_size=record.batch_size))["state_value"].reshape(-1))
    return torch.stack(values, -1)


def goal_groups(images: np.ndarray, fov: float) -> np.ndarray:
    """Each view's group (an index of :data:`GROUPS`): where the goal's pixels are across the view."""
    bearing, _ = goal_in_view(images, fov)
    third = math.radians(fov) / 6  # the bearing of a third's edge from the axis, near enough
    group = np.where(bearing > third, 1, np.where(bearing < -third, 3, 2))
    return np.where(np.isnan(bearing), 0, group)


def main(argv: list[str] | None = None) -> int:
    """Play, value every look, print the table."""
    parser = ArgumentParser(prog="look_values.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("run", help="a run directory (holding checkpoint.pt)")
    parser.add_argument("--rooms", type=whole_number, default=16, help="rooms played at once (16)")
    parser.add_argument("--cycles", type=whole_number, default=150, help="cycles played in each room (150)")
    parser.add_argument("--epsilon", type=float, default=0.3, help="probability of a random look (0.3)")
    parser.add_argument("--seed", type=whole_number, default=0, help="seed of the layouts and the sampling (0)")
    parser.add_argument("--csv", type=Path, help="add the groups' rows to this CSV (replacing the run's rows)")
    args = parser.parse_args(argv)
    if args.rooms < 1 or args.cycles < 1 or not 0 <= args.epsilon <= 1:
        parser.error("--rooms and --cycles must be >= 1 and --epsilon a probability")
    config = load_run_config(args.run)
    method = make_method(config, torch.device("cpu"), start=False)
    restore_method(method, load_checkpoint(f"{args.run}/{CHECKPOINT}"), args.run)
    env = make_env(
        args.rooms,
        looker=HoldOrExplore(args.epsilon),
        seed=args.seed,
        split="eval",
        look_views=True,
        frame_stack=config.stacked_views,
        config=config.env,
    )
    torch.manual_seed(args.seed)
    try:
        with set_exploration_type(ExplorationType.RANDOM), torch.no_grad():
            data = env.rollout(args.cycles, method.actor, break_when_any_done=False)
    finally:
        env.close()
    record = data["next", LOOKER].reshape(-1)[~data["next", "done"].reshape(-1)]  # looks that a move followed
    values = look_values(method.critic, record)
    gain = (values - values[:, HOLD : HOLD + 1]).numpy()
    groups = goal_groups(latest_view(record["observation", "image"]).numpy(), config.env.fov)
    greedy = probs = None
    phi2 = method.modules.get("phi2")
    if phi2 is not None:
        inputs = TensorDict({(LOOKER, "observation"): record["observation"]}, batch_size=record.batch_size)
        with torch.no_grad():
            logits = phi2[0](inputs)[LOOKER, "logits"]
            greedy, probs = logits.argmax(-1).numpy(), logits.softmax(-1).numpy()
    print(f"{args.run}: {config.method}, {len(record)} looks of {args.rooms} held-out rooms, epsilon {args.epsilon}")
    print(
        "goal in s_bar  | looks | Q(left)-Q(hold) Q(right)-Q(hold) | best: left  right | phi2 greedy: left hold right"
        " | phi2 mean p: left hold right"
    )
    lines = []
    for index, name in enumerate(GROUPS):
        rows = groups == index
        if not rows.any():
            continue
        left, right = gain[rows, 0], gain[rows, 2]
        shares = (np.mean(left > np.maximum(right, 0)), np.mean(right > np.maximum(left, 0)))
        picks = [np.mean(greedy[rows] == u) for u in range(3)] if greedy is not None else []
        mean_p = list(probs[rows].mean(0)) if probs is not None else []
        cells = " ".join(f"{x:.2f}" for x in picks) or "-"
        cells += " | " + (" ".join(f"{p:.2f}" for p in mean_p) or "-")
        best = f"{shares[0]:.2f}  {shares[1]:.2f}"
        print(f"{name:14s} | {rows.sum():5d} | {left.mean():+15.4f} {right.mean():+16.4f} | {best:>17s} | {cells}")
        numbers = [left.mean(), right.mean(), *shares, *(picks or [math.nan] * 3), *(mean_p or [math.nan] * 3)]
        lines.append([args.run, name, int(rows.sum()), *(f"{x:.4f}" for x in numbers)])
    if args.csv and lines:
        where = [portable.machine(), datetime.date.today().isoformat()]
        write_rows(args.csv, [dict(zip(COLUMNS, line + where, strict=True)) for line in lines], COLUMNS)
        print(f"wrote {args.csv}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
