"""Where a training method's collection time goes: physics, renders, network forward passes, the rest.

The method is built as ``activeperc-train`` builds it (``TrainConfig`` defaults but for ``--method`` and
``--num-envs``; networks on the CPU, collection in this process), ``--warmup-iters`` iterations run untimed,
then ``--iterations`` are timed. Inside the collectors (``Method._next``) the script adds up the time spent in

- ``Simulator.move`` (the physics of one control period, reward and episode logic),
- ``Simulator.look`` (the pan joint set for the looker's actions),
- ``Simulator.reset`` and ``Simulator.render`` (the first-person views, ``s_bar`` and ``s'``),
- ``Head.forward`` (every network's forward pass: the mover's policy and the looker in the loop),

and prints each per collected cycle of all rooms (one env step), with the rest of the collection time
(TorchRL and tensordict bookkeeping, action sampling, auto-reset) and the learning time per iteration.
Run it from the repository root::

    python benchmarks/collect_breakdown.py                       # meta, 16 rooms, 10 iterations
    python benchmarks/collect_breakdown.py --method fixed_forward --num-envs 64
"""

from __future__ import annotations

import argparse
import functools
import time
from collections import defaultdict

PARTS = (
    ("physics (Simulator.move)", "activeperc_env.core", "Simulator", "move"),
    ("look (Simulator.look)", "activeperc_env.core", "Simulator", "look"),
    ("resets (Simulator.reset)", "activeperc_env.core", "Simulator", "reset"),
    ("renders (Simulator.render)", "activeperc_env.core", "Simulator", "render"),
    ("network forward passes (Head.forward)", "activeperc_rl.models", "Head", "forward"),
)


def breakdown(method_name: str, num_envs: int, iterations: int, warmup_iters: int) -> dict:
    """Seconds spent in each part of :data:`PARTS` while collecting, the collection and learning totals, and the
    number of env steps collected, over ``iterations`` timed iterations."""
    import importlib

    import torch

    from activeperc_rl.config import TrainConfig
    from activeperc_rl.methods import make_method

    config = TrainConfig(method=method_name, num_envs=num_envs, device="cpu")
    torch.manual_seed(config.seed)
    method = make_method(config, torch.device("cpu"))
    spent: dict[str, float] = defaultdict(float)
    state = {"collecting": False, "steps": 0}

    def timed(label, function):
        @functools.wraps(function)
        def wrapper(*args, **kwargs):
            if not state["collecting"]:
                return function(*args, **kwargs)
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                spent[label] += time.perf_counter() - start

        return wrapper

    originals = []
    for label, module, owner, name in PARTS:
        cls = getattr(importlib.import_module(module), owner)
        originals.append((cls, name, getattr(cls, name)))
        setattr(cls, name, timed(label, getattr(cls, name)))
    next_rollout = method._next  # bound method of the library, wrapped on this instance only

    def timed_next(collector):
        state["collecting"] = True
        start = time.perf_counter()
        try:
            rollout = next_rollout(collector)
        finally:
            spent["collection"] += time.perf_counter() - start
            state["collecting"] = False
        state["steps"] += rollout.shape[-1]
        return rollout

    method._next = timed_next
    try:
        for _ in range(warmup_iters):
            method.iterate()
        spent.clear()
        state["steps"] = 0
        start = time.perf_counter()
        for _ in range(iterations):
            method.iterate()
        total = time.perf_counter() - start
    finally:
        for cls, name, original in originals:
            setattr(cls, name, original)
        method.close()
    return dict(spent) | {"total": total, "steps": state["steps"], "iterations": iterations}


def main() -> None:
    """Parse the flags, time the iterations and print the breakdown."""
    from activeperc_rl.config import TrainConfig
    from activeperc_rl.methods import METHODS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--method", choices=METHODS, default="meta", help="the method to time (meta)")
    parser.add_argument("--num-envs", type=int, default=TrainConfig().num_envs, help="rooms per environment (16)")
    parser.add_argument("--iterations", type=int, default=10, help="timed iterations (10)")
    parser.add_argument("--warmup-iters", type=int, default=2, help="untimed iterations first (2)")
    parser.add_argument(
        "--threads",
        type=int,
        default=TrainConfig().torch_threads,
        help="torch threads while collecting (default: as training); learning runs on TrainConfig.learner_threads",
    )
    args = parser.parse_args()
    for flag in ("num_envs", "iterations", "threads"):
        if getattr(args, flag) < 1:
            parser.error(f"--{flag.replace('_', '-')}={getattr(args, flag)} is invalid: expected an int >= 1")
    if args.warmup_iters < 0:
        parser.error(f"--warmup-iters={args.warmup_iters} is invalid: expected an int >= 0")

    import torch

    from activeperc_rl.allocator import keep_freed_memory

    torch.set_num_threads(args.threads)
    keep_freed_memory()  # as activeperc-train does
    result = breakdown(args.method, args.num_envs, args.iterations, args.warmup_iters)
    steps, collection = result["steps"], result["collection"]
    print(f"{args.method}, {args.num_envs} rooms, {args.iterations} iterations, torch on {args.threads} thread(s)")
    print(f"collection: {steps} env steps of {args.num_envs} rooms, {collection / steps * 1e3:.1f} ms per step")
    parts = 0.0
    for label, *_ in PARTS:
        seconds = result.get(label, 0.0)
        parts += seconds
        print(f"  {label:<40}{seconds / steps * 1e3:7.2f} ms per step  ({seconds / collection:4.0%})")
    rest = collection - parts
    label = "the rest (TorchRL, tensordict, sampling)"
    print(f"  {label:<40}{rest / steps * 1e3:7.2f} ms per step  ({rest / collection:4.0%})")
    learn = result["total"] - collection
    print(f"learning: {learn / args.iterations * 1e3:.0f} ms per iteration ({learn / result['total']:.0%} of the time)")


if __name__ == "__main__":
    main()
