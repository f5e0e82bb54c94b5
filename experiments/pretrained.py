"""Ship trained runs as the package's pretrained policies and score the shipped files on held-out layouts.

Each run directory becomes ``activeperc_rl/weights/fovF.pt`` (F its field of view; :func:`~activeperc_rl.policies.
save_policy`, half precision), which is then played on ``--episodes`` held-out layouts: the learned mover and
looker, the same mover with the camera held forward, and random play. Run from the repository root::

    python experiments/pretrained.py runs/pretrained/fov60 runs/pretrained/fov100 \
        --csv experiments/results/pretrained.csv
"""

from __future__ import annotations

import datetime
import json
import os
import sys
from pathlib import Path

from activeperc_env.arguments import ArgumentParser, whole_number
from activeperc_rl.evaluate import evaluate
from activeperc_rl.models import FixedLooker
from activeperc_rl.policies import PRETRAINED, WEIGHTS, load_policy_file, save_policy
from activeperc_rl.recipe import TrainConfig
from activeperc_rl.runtime import portable
from activeperc_rl.runtime.atomic import write_csv
from activeperc_rl.runtime.checkpoint import load_run_config

COLUMNS = ("policy", "frames", "learned", "camera_held", "random", "run_learned", "episodes", "trained_by")
COLUMNS += ("command", "machine", "date")
RECIPE = ("method", "options", "a2c", "network", "env")
"""The parts of a run's config that must be the default recipe's (at the run's field of view) for it to ship."""


def shipped_name(run: Path) -> str:
    """The name ``run`` ships under (``fovF``); ``ValueError`` unless it is a run of the default recipe at the field
    of view of a shipped policy."""
    config = load_run_config(run)
    name = f"fov{config.env.fov:g}"
    if name not in PRETRAINED:
        raise ValueError(f"run {str(run)!r} is at {name}: the shipped policies are {tuple(PRETRAINED)}")
    default = TrainConfig().replace(fov=config.env.fov)
    differ = [part for part in RECIPE if getattr(config, part) != getattr(default, part)]
    if differ:
        raise ValueError(f"run {str(run)!r} is not the default recipe at {name}: its {', '.join(differ)} differ")
    return name


def ship(run: Path, name: str, episodes: int) -> dict:
    """Write ``run``'s policy file, score it, then put it in the package: one row of the CSV."""
    shipped = WEIGHTS / f"{name}.pt"
    scored = WEIGHTS / f".{name}.pt.new"  # in the package only once scored
    try:
        about = save_policy(run, scored, trained_by=PRETRAINED[name])
        config, mover_policy, looker = load_policy_file(scored)
        scores = {
            "learned": (mover_policy, looker),
            "camera_held": (mover_policy, FixedLooker()),
            "random": (None, None),
        }
        row = {"policy": name, "frames": about["frames"], "episodes": episodes, "trained_by": PRETRAINED[name]}
        for column, (mover, look) in scores.items():
            row[column] = evaluate(config, mover, look, episodes=episodes, seed=0)["success_rate"]
        row["run_learned"] = json.loads(about["eval"])["learned"]["success_rate"] if about["eval"] else ""
        os.replace(scored, shipped)
    finally:
        scored.unlink(missing_ok=True)
    return row


def main(argv: list[str] | None = None) -> int:
    """Ship each run given and write the table of the shipped files' held-out success."""
    parser = ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run directories, one per field of view")
    parser.add_argument("--episodes", type=whole_number, default=100, help="held-out episodes a policy (seed 0)")
    parser.add_argument("--csv", type=Path, help="write the table here")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    try:
        names = [shipped_name(run) for run in args.runs]
    except ValueError as error:
        parser.error(str(error))
    command = "python experiments/pretrained.py " + " ".join(sys.argv[1:] if argv is None else argv)
    stamp = {"command": command, "machine": portable.machine(), "date": datetime.date.today().isoformat()}
    rows = [ship(run, name, args.episodes) | stamp for run, name in zip(args.runs, names, strict=True)]
    for row in rows:
        print(json.dumps({key: row[key] for key in COLUMNS[:6]}))
    if args.csv:
        write_csv(args.csv, COLUMNS, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
