"""Which part of a run's looker costs its mover success? The mover of a ``meta`` or ``ia2c`` run scored with lookers
that mix its own looker (``meta``'s ``phi1``) with the scripted tracking looker, and with its critic's best look.

Run from the repository root::

    python experiments/looker_swap.py runs/meta-seed0-TIME
    python experiments/looker_swap.py RUN... --episodes 200 --csv swap.csv

Each run's mover plays ``--episodes`` held-out episodes (as ``activeperc-eval`` does) with four lookers: its own
(``phi1``, as at test time; ``ia2c``'s looker in its place); ``phi1`` while the goal is in the looker's view and a
random pan (or a hold) while it is not;
:class:`~activeperc_env.scripted.TrackLooker`'s look (centre the goal) while it is in view and ``phi1``'s while it
is not; the tracking looker alone; and the look whose view the run's critic values most (the label ``meta``'s
``best_look`` credit trains ``phi2`` toward, taken as the look: what ``phi2`` would do if it fitted its labels).
``--lookers`` picks some of them. The mover was trained beside its own looker, so a looker that beats it here
does so for a mover that never learned with it. With ``--lookers-of RUN...`` each mover also plays with those runs'
lookers (``meta``'s and ``ia2c``'s swapped: is a method ahead by its looker or by its mover?).
"""

from __future__ import annotations

import datetime
import os
import sys

import numpy as np
import torch
from scripted_looker_training import ScriptedLooker
from torch import nn

from activeperc_env.arguments import ArgumentParser, whole_number
from activeperc_env.scripted import goal_in_view
from activeperc_rl.envs import LOOKER, latest_view
from activeperc_rl.evaluate import MAX_ROOMS, evaluate
from activeperc_rl.losses import best_looks, view_values
from activeperc_rl.runtime import portable
from activeperc_rl.runtime.atomic import write_csv
from activeperc_rl.runtime.checkpoint import CHECKPOINT, load_checkpoint, restored_method

LOOKERS = (
    "phi1",
    "phi1 in view, random pan out of view",
    "phi1 in view, hold out of view",
    "track in view, phi1 out of view",
    "track",
    "critic's best look",
)
COLUMNS = ["run", "looker", "episodes", "success_rate", "mean_return", "machine", "date"]


class InViewOrNot(nn.Module):
    """Writes ``in_view``'s look where the goal is in the looker's view ``s_bar`` and ``out_of_view``'s elsewhere."""

    def __init__(self, in_view: nn.Module, out_of_view: nn.Module, fov: float):
        super().__init__()
        self.in_view, self.out_of_view, self.fov = in_view, out_of_view, fov

    def forward(self, tensordict):
        """Write the looks of every room into ``tensordict``."""
        looks = [module(tensordict.copy()).get((LOOKER, "action")) for module in (self.in_view, self.out_of_view)]
        image = latest_view(tensordict.get((LOOKER, "observation", "image"))).cpu().numpy()
        bearing, _ = goal_in_view(image, self.fov)
        seen = torch.as_tensor(~np.isnan(bearing), device=looks[0].device)
        tensordict.set((LOOKER, "action"), torch.where(seen, *looks))
        return tensordict


class BestLook(nn.Module):
    """Takes in every room the look whose view ``critic`` values most, 'hold' on a tie (meta's ``best_look`` label);
    it reads the views of the env's ``look_views``."""

    def __init__(self, critic: nn.Module, mirrored: bool = False):
        super().__init__()
        self.critic, self.mirrored = critic, mirrored

    def forward(self, tensordict):
        """Write the looks of every room into ``tensordict``."""
        views = tensordict.get((LOOKER, "look_views"))
        values = view_values(self.critic, tensordict, views, LOOKER, self.critic.out_keys[0], self.mirrored)
        tensordict.set((LOOKER, "action"), best_looks(values))
        return tensordict


def policy_of(run: str):
    """The run's config, mover, looker (``meta``'s ``phi1``, ``ia2c``'s looker) and the mover's critic;
    ``SystemExit`` naming a run of a method without a looker of its own."""
    config, method = restored_method(load_checkpoint(f"{run}/{CHECKPOINT}"), run, torch.device("cpu"))
    mover, looker = method.policy()
    if looker is None:  # joint and curriculum pick both actions from the mover's view; fixed_forward holds
        raise SystemExit(
            f"looker_swap: {run} is a {config.method} run, without a looker of its own: it needs meta or ia2c"
        )
    return config, mover, looker, method.critic


def rows_of_run(
    run: str, episodes: int, seed: int, lookers_of: tuple[str, ...] = (), names: tuple[str, ...] = LOOKERS
) -> list[dict]:
    """The run's mover scored with each of ``names`` (of :data:`LOOKERS`), then with the looker of each run of
    ``lookers_of``."""
    config, mover, phi1, critic = policy_of(run)
    track = ScriptedLooker("track", config.env, MAX_ROOMS, seed)
    fov = config.env.fov
    mirrored = getattr(config.options, "mirror_looks", False)
    ours = {
        "phi1": phi1,
        "phi1 in view, random pan out of view": InViewOrNot(phi1, track, fov),
        "phi1 in view, hold out of view": InViewOrNot(phi1, ScriptedLooker("fixed", config.env, MAX_ROOMS), fov),
        "track in view, phi1 out of view": InViewOrNot(track, phi1, fov),
        "track": track,
        "critic's best look": BestLook(critic, mirrored),
    }
    others = [other for other in lookers_of if other != run]
    lookers = {name: ours[name] for name in names}
    for other in others:
        other_config, _, looker, _ = policy_of(other)
        if other_config.env != config.env:
            raise SystemExit(f"looker_swap: {other} was trained in another room than {run}: {other_config.env}")
        lookers[f"looker of {other}"] = looker
    rows = []
    for name, looker in lookers.items():
        views = isinstance(looker, BestLook)
        score = evaluate(config, mover, looker, episodes=episodes, seed=seed, look_views=views)
        rows.append({"run": run, "looker": name} | {key: score[key] for key in COLUMNS[2:5]})
    return rows


def main(argv: list[str] | None = None) -> int:
    """Score every run's mover with each looker, print the rows (and write them with ``--csv``)."""
    parser = ArgumentParser(prog="looker_swap.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", help="meta or ia2c run directories (holding checkpoint.pt)")
    parser.add_argument("--episodes", type=whole_number, default=200, help="held-out episodes a looker (200)")
    parser.add_argument("--seed", type=whole_number, default=0, help="seed of the layouts and the sampling (0)")
    parser.add_argument("--lookers-of", nargs="+", default=[], help="runs whose lookers every mover also plays with")
    parser.add_argument(
        "--lookers", nargs="+", choices=LOOKERS, default=list(LOOKERS), metavar="LOOKER", help=f"of {LOOKERS} (all)"
    )
    parser.add_argument("--csv", help="also write the rows here")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    missing = [
        run for run in dict.fromkeys([*args.runs, *args.lookers_of]) if not os.path.isfile(f"{run}/{CHECKPOINT}")
    ]
    if missing:
        parser.error(f"{', '.join(map(repr, missing))}: no {CHECKPOINT} there (run directories of activeperc-train)")
    where = {"machine": portable.machine(), "date": datetime.date.today().isoformat()}
    print(" | ".join(COLUMNS))
    rows = []
    for run in args.runs:
        for row in rows_of_run(run, args.episodes, args.seed, tuple(args.lookers_of), tuple(args.lookers)):
            rows.append(row | where)
            print(" | ".join(str(rows[-1][column]) for column in COLUMNS), flush=True)
    if args.csv:
        write_csv(args.csv, COLUMNS, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
