"""Can a ``meta`` run's looker tell the best look from its view? Copies of its ``phi2`` refitted on fresh labels say.

Run from the repository root::

    python experiments/looker_refit.py runs/meta-seed0-TIME
    python experiments/looker_refit.py RUN... --cycles 200 --steps 300 --lr 3e-4 1e-3 --csv refit.csv

The run's mover plays ``--rooms`` rooms for ``--cycles`` cycles twice, on training layouts and then on held-out
ones, with E2's looker (the run's ``phi2``, epsilon-greedy at the run's ``epsilon``), drawing the views of all three
looks in every cycle. Each look that a move followed is labelled as the ``best_look`` credit labels it: the look
whose view the mover's critic values most, 'hold' unless a pan's view is valued above holding. Copies of ``phi2``
then take ``--steps`` Adam steps of the ``best_look`` loss (cross-entropy toward the label) on the training
cycles, ``--batch`` cycles a step in turn, at each ``--lr``. For ``phi2``, ``phi1`` and each copy it prints, on the
held-out cycles: how often the greedy look is the label (``agreement``), the same on the cycles where a pan beats
holding by more than ``--margin`` (``agreement_pan``), and the cross-entropy. A copy that agrees far more often than
the run's own ``phi2`` says the labels are predictable from the view and the run's looker had not learned them.
With ``--episodes N`` the run's mover also plays ``N`` held-out episodes with each of them, greedy, as its looker
(``success_rate``): does a looker that fits its labels better take its mover further?

``--fresh-frames K...`` also fits untrained lookers (``phi2``'s network, seeded alike) that read the views of the
latest ``K`` cycles (``looker_frames``), ``--fresh-steps`` Adam steps each: does a looker that remembers predict
the labels better than one of the same training that sees only the view before its look?
"""

from __future__ import annotations

import copy
import datetime
import sys

import torch
from look_values import look_values
from tensordict import TensorDict
from torchrl.envs.utils import ExplorationType, set_exploration_type

from activeperc_env.arguments import ArgumentParser, whole_number
from activeperc_env.core import HOLD
from activeperc_rl.envs import LOOKER, MAX_FRAME_STACK, make_env
from activeperc_rl.evaluate import evaluate
from activeperc_rl.losses import best_looks
from activeperc_rl.models import EpsilonGreedyLooker, make_actor, start_holding
from activeperc_rl.runtime import portable
from activeperc_rl.runtime.atomic import write_csv
from activeperc_rl.runtime.checkpoint import CHECKPOINT, load_checkpoint, restored_method

COLUMNS = (
    "run", "looker", "steps", "lr", "cycles", "agreement", "agreement_pan", "pan_cycles", "cross_entropy",
    "episodes", "success_rate", "machine", "date",
)  # fmt: skip


def labelled_looks(method, config, rooms: int, cycles: int, split: str, seed: int):
    """The looker's inputs at the looks a move followed (``rooms * cycles`` at most) in ``split``'s layouts, and their
    ``best_look`` labels and gains ``max_u Q(u) - Q(hold)`` (the inputs stack ``config.stacked_views`` views)."""
    looker = EpsilonGreedyLooker(method.phi2, method.options.epsilon)
    frames = config.stacked_views
    env = make_env(rooms, looker=looker, seed=seed, split=split, look_views=True, frame_stack=frames, config=config.env)
    torch.manual_seed(seed)
    try:
        with set_exploration_type(ExplorationType.RANDOM), torch.no_grad():
            data = env.rollout(cycles, method.actor, break_when_any_done=False)
    finally:
        env.close()
    record = data["next", LOOKER].reshape(-1)[~data["next", "done"].reshape(-1)]
    values = look_values(method.critic, record)
    gain = values.max(-1).values - values[:, HOLD]
    inputs = TensorDict({(LOOKER, "observation"): record["observation"]}, batch_size=record.batch_size)
    return inputs, best_looks(values), gain


def score(actor, record, labels: torch.Tensor, gain: torch.Tensor, margin: float) -> dict:
    """``actor``'s greedy agreement with ``labels`` (overall, and where a pan gains more than ``margin``) and its
    cross-entropy toward them."""
    with torch.no_grad():
        logits = actor.get_dist(record).logits.reshape(len(labels), -1)
    agree = logits.argmax(-1) == labels
    pans = gain > margin
    return {
        "cycles": len(labels),
        "agreement": f"{agree.float().mean():.3f}",
        "agreement_pan": f"{agree[pans].float().mean():.3f}" if pans.any() else "",
        "pan_cycles": int(pans.sum()),
        "cross_entropy": f"{torch.nn.functional.cross_entropy(logits, labels):.4f}",
    }


def refit(phi2, record, labels: torch.Tensor, steps: int, lr: float, batch: int):
    """A copy of ``phi2`` after ``steps`` Adam steps (the run's optimizer's ``eps``) of cross-entropy toward
    ``labels``, ``batch`` cycles a step in turn."""
    actor = copy.deepcopy(phi2).requires_grad_(True)
    optimizer = torch.optim.Adam(actor.parameters(), lr=lr, eps=1e-5)
    for step in range(steps):
        start = step * batch % len(labels)
        rows = torch.arange(start, start + batch) % len(labels)
        dist = actor.get_dist(record[rows])
        loss = -dist.log_prob(labels[rows].reshape(dist.batch_shape)).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    return actor


def fresh_looker(config, frames: int, seed: int):
    """An untrained ``phi2`` of ``config``'s networks (its output layer zero: every look alike) reading the latest
    ``frames`` views."""
    torch.manual_seed(seed)
    actor = make_actor(config.network.encoder(config.env, False, frames), config.network.hidden_size, LOOKER)
    start_holding(actor, 1 / 3)
    return actor


def rows_of_run(run: str, args) -> list[dict]:
    """Every looker's scores on ``run``'s held-out cycles."""
    config, method = restored_method(load_checkpoint(f"{run}/{CHECKPOINT}"), run, torch.device("cpu"))
    if config.method != "meta":
        raise SystemExit(f"looker_refit: {run} is a {config.method} run; it needs a meta run")
    if args.fresh_frames and config.options.looker_encoder != "own":
        raise SystemExit(f"looker_refit: --fresh-frames needs a run of looker_encoder 'own'; {run} has another")
    if max(args.fresh_frames, default=1) > config.stacked_views:  # the inputs stack the most views any looker reads
        config = config.replace(looker_frames=max(args.fresh_frames))
    train = labelled_looks(method, config, args.rooms, args.cycles, "train", args.seed)
    test = labelled_looks(method, config, args.rooms, args.cycles, "eval", args.seed)
    lookers = [("phi2", 0, "", method.phi2), ("phi1", 0, "", method.phi1)]
    lookers += [("phi2", args.steps, lr, refit(method.phi2, *train[:2], args.steps, lr, args.batch)) for lr in args.lr]
    for frames in args.fresh_frames:
        fresh = fresh_looker(config, frames, args.seed)
        name = f"fresh, {frames} view{'s' if frames > 1 else ''}"
        lookers += [
            (name, args.fresh_steps, lr, refit(fresh, *train[:2], args.fresh_steps, lr, args.batch)) for lr in args.lr
        ]
    rows = []
    for name, steps, lr, actor in lookers:
        row = {"run": run, "looker": name, "steps": steps, "lr": lr} | score(actor, *test, args.margin)
        if args.episodes:
            row["episodes"], looker = args.episodes, EpsilonGreedyLooker(actor, 0.0)
            row["success_rate"] = evaluate(config, method.actor, looker, episodes=args.episodes, seed=args.seed)[
                "success_rate"
            ]
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    """Score and refit every run's looker, print the rows (and write them with ``--csv``)."""
    parser = ArgumentParser(prog="looker_refit.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", help="meta run directories (holding checkpoint.pt)")
    parser.add_argument("--rooms", type=whole_number, default=32, help="rooms played at once (32)")
    parser.add_argument("--cycles", type=whole_number, default=200, help="cycles played in each room (200)")
    parser.add_argument("--steps", type=whole_number, default=300, help="Adam steps of each refit (300)")
    parser.add_argument("--batch", type=whole_number, default=256, help="cycles a step (256, a D2's)")
    parser.add_argument("--lr", type=float, nargs="+", default=[3e-4, 1e-3], help="learning rates (3e-4 1e-3)")
    parser.add_argument("--margin", type=float, default=0.03, help="a pan's gain over holding that counts (0.03)")
    parser.add_argument("--seed", type=whole_number, default=0, help="seed of the layouts and the sampling (0)")
    parser.add_argument("--episodes", type=whole_number, default=0, help="held-out episodes with each looker (0)")
    parser.add_argument("--fresh-frames", type=whole_number, nargs="*", default=[], help="views of fresh lookers")
    parser.add_argument("--fresh-steps", type=whole_number, default=2000, help="Adam steps of each fresh looker (2000)")
    parser.add_argument("--csv", help="also write the rows here")
    args = parser.parse_args(argv)
    if min(args.rooms, args.cycles, args.batch) < 1 or not all(lr > 0 for lr in args.lr):
        parser.error("--rooms, --cycles and --batch must be >= 1 and every --lr > 0")
    if not all(1 <= frames <= MAX_FRAME_STACK for frames in args.fresh_frames):
        parser.error(f"--fresh-frames {args.fresh_frames}: expected views in 1 .. {MAX_FRAME_STACK}")
    where = {"machine": portable.machine(), "date": datetime.date.today().isoformat()}
    rows = [row | where for run in args.runs for row in rows_of_run(run, args)]
    print(" | ".join(COLUMNS))
    for row in rows:
        print(" | ".join(str(row.get(column, "")) for column in COLUMNS), flush=True)
    if args.csv:
        write_csv(args.csv, COLUMNS, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
