"""What each Figure 1 method does with 1,000,000 environment frames: the frames each of its learners learns from and
how many updates each takes, counted over a few iterations of its preset.

Every optimizer step of a method goes through ``Method._step``; this script counts those steps and the frames of the
rollout each one learns from (its first input: for ``meta``'s looker, D2, whose baseline also reads D1), and scales
them to 1,000,000 of the frames the method collects (E1 and E2 both, for ``meta``). Joint and Curriculum have one
agent that picks the move and the look, so its updates are the mover's and the looker's. Run from the repository
root::

    python experiments/fig1/budget.py --csv experiments/results/budget.csv
    python experiments/fig1/budget.py --only meta_eps0.3_fov60 fixed_forward_fov60 --iterations 2
"""

from __future__ import annotations

import sys
from collections import defaultdict
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
import sweep  # noqa: E402

from activeperc_env.arguments import ArgumentParser, whole_number  # noqa: E402
from activeperc_rl.config import load_yaml  # noqa: E402
from activeperc_rl.recipe import TrainConfig, make_method  # noqa: E402
from activeperc_rl.runtime.atomic import write_csv  # noqa: E402

PER = 1_000_000
"""The environment frames every count is scaled to."""
COLUMNS = (
    "method",
    "num_envs",
    "rollout_length",
    "frames_per_iteration",
    "mover_updates",
    "mover_frames",
    "looker_updates",
    "looker_frames",
)
LEARNERS = {"mover": ("mover", "joint"), "looker": ("looker", "joint")}
"""The optimizers (``Method._step``'s names) of each learner: the joint agent is both."""


def count_updates(config: TrainConfig, iterations: int) -> dict:
    """Run ``iterations`` iterations of ``config``'s method; its CSV row: the frames it collected per iteration and,
    per :data:`PER` of them, each learner's updates and the frames those updates learned from."""
    torch.manual_seed(config.run.seed)
    method = make_method(config, torch.device("cpu"))
    steps = defaultdict(lambda: [0, 0])  # optimizer name: [updates, frames learned from]
    take_step = method._step

    def counted(name, loss, *inputs):
        steps[name][0] += 1
        steps[name][1] += inputs[0].numel()
        return take_step(name, loss, *inputs)

    method._step = counted
    try:
        frames = sum(method.iterate().frames for _ in range(iterations))
    finally:
        method.close()
    row = {
        "num_envs": config.run.num_envs,
        "rollout_length": config.run.rollout_length,
        "frames_per_iteration": frames // iterations,
    }
    for learner, names in LEARNERS.items():
        updates, learned = (sum(steps[name][i] for name in names) for i in (0, 1))
        row[f"{learner}_updates"] = round(updates * PER / frames)
        row[f"{learner}_frames"] = round(learned * PER / frames)
    return row


def main(argv: list[str] | None = None) -> int:
    """Count every preset's budget; print the table and write ``--csv``."""
    parser = ArgumentParser(prog="budget.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--room", choices=sweep.ROOMS, default="v3", help="the room's presets (default v3)")
    parser.add_argument("--only", nargs="+", metavar="CONFIG", help="these configs only (names without .yaml)")
    parser.add_argument("--fov", type=int, default=60, help="the presets of this field of view (default 60)")
    parser.add_argument("--iterations", type=whole_number, default=3, help="iterations counted per method (3)")
    parser.add_argument("--csv", type=Path, help="write the rows here")
    args = parser.parse_args(argv)
    if args.iterations < 1:
        parser.error(f"--iterations {args.iterations}: expected at least 1")
    try:
        paths = sweep.find_configs(only=args.only, root=sweep.CONFIGS / args.room)
    except ValueError as error:
        parser.error(str(error))
    rows = []
    for path in paths:
        task = sweep.Task(path, 0)
        if task.fov != args.fov:
            continue
        config = TrainConfig.from_dict(load_yaml(path)).replace(eval_episodes=0)
        rows.append({"method": task.method} | count_updates(config, args.iterations))
        print(" ".join(f"{key}={rows[-1][key]}" for key in COLUMNS), flush=True)
    if args.csv:
        write_csv(args.csv, COLUMNS, rows)
        print(f"wrote {args.csv}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
