"""Training speed of every method against MiniWorld's raw env speed, measured in one run.

With ``--parts``: where each method's collection time goes (physics, renders, the networks' forward passes, the rest).

Run it from the repository root (MiniWorld comes with the ``bench`` extra; ``pip install -e .[train,bench]``)::

    python benchmarks/train_speed.py                      # 20 s per method, 3 rounds (about 7 minutes)
    python benchmarks/train_speed.py --methods meta --seconds 10 --threads 2
    python benchmarks/train_speed.py --seconds 5 --rounds 1 --json
    python benchmarks/train_speed.py --methods meta --collector inprocess process ray --workers 2
    python benchmarks/train_speed.py --methods meta --parts --seconds 10 --rounds 1 --no-peer
    python benchmarks/train_speed.py --methods meta fixed_forward --flip reuse_features --no-peer
    python benchmarks/train_speed.py --methods meta --variant num_envs=32 rollout_length=8 --no-peer
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import json
import statistics
import sys
import time
from pathlib import Path

import harness
import peer

from activeperc_rl.runtime import portable
from activeperc_rl.runtime.atomic import atomic_path

GOALS = (  # (name, multiple of MiniWorld's raw steps/s that meta must reach)
    ("meta >= 1.0x MiniWorld raw env speed on 2 cores", 1.0),
    ("stretch: meta >= 1.5x MiniWorld raw env speed on 2 cores", 1.5),
)
GPU_GOAL = 20_000  # meta training frames/s on an H100 with 16 cores
PART_LABELS = harness.SIMULATOR_PARTS | {
    "look_views": "look views (Simulator.look_views)",
    "forward": "network forward passes (Head.forward)",
}
WIDTH = 32  # of a run's label in the report


def collection_parts() -> list[tuple[type, tuple[str, ...]]]:
    """The classes whose methods ``--parts`` times within the collections, each with those methods' names."""
    from activeperc_env.core import Simulator
    from activeperc_rl.models import Head

    return [(Simulator, (*harness.SIMULATOR_PARTS, "look_views")), (Head, ("forward",))]


def time_collections(method, stopwatch: harness.Stopwatch, parts: bool) -> None:
    """Time ``method``'s collections (its ``_next``, wrapped on this instance only) as the part ``collect`` of
    ``stopwatch`` and, with ``parts``, the methods of :func:`collection_parts` within them: their classes are patched
    only while a collection runs, so learning's forward passes are not counted."""
    next_rollout = stopwatch.timed("collect", method._next, whole=True)
    owners = collection_parts() if parts else []

    def collect(collector):
        with contextlib.ExitStack() as watching:
            for owner, methods in owners:
                watching.enter_context(stopwatch.watching(owner, methods))
            return next_rollout(collector)

    method._next = collect


def iterate_for(method, seconds: float) -> tuple[int, int, dict, float]:
    """Run ``method.iterate()`` until ``seconds`` have passed; return the frames, the iterations, the last
    iteration's losses and the wall time."""
    frames, iterations = 0, 0
    start = time.perf_counter()
    while True:
        iteration = method.iterate()
        frames += iteration.frames
        iterations += 1
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            return frames, iterations, iteration.losses, elapsed


def bench_method(
    name: str,
    num_envs: int | None,
    seconds: float,
    warmup_iters: int,
    device: str = "cpu",
    collect_workers: int = 0,
    collector: str = "process",
    parts: bool = False,
    backend: str = "mujoco",
    recipe: dict | None = None,
    version: int | None = None,
    options: dict | None = None,
) -> dict:
    """Train ``name`` on ``device`` for ``warmup_iters`` untimed iterations, then for ``seconds``; return its figures.

    The method is built as ``activeperc-train`` builds it: the default :class:`~activeperc_rl.recipe.TrainConfig` (or
    the preset ``recipe``, in room ``version`` if given, with the training ``options`` by name) but for the method,
    ``num_envs`` (``None``: the default),
    ``collect_workers`` (workers per environment; their start is not timed) and ``collector`` (``process`` or
    ``ray``, for the workers).

    The result holds ``frames_per_s`` (frames, every room's cycles in every environment, over the timed wall time),
    ``iterations``, ``frames``, ``frames_per_iteration``, ``seconds`` (the timed wall time), ``collect_s`` (time
    inside the collectors: the rooms, the policy's and the in-loop looker's forward passes), ``learn_s`` (the rest:
    losses, backward passes, optimizer and soft updates), with ``parts`` ``parts_s`` (seconds in each method of
    :data:`PART_LABELS` while collecting) and, for ``curriculum``, ``obstacles`` (the timed phase's obstacle count).
    """
    import torch

    from activeperc_rl.envs import torch_device
    from activeperc_rl.recipe import TrainConfig, make_method

    changes = {"method": name, "device": device, "collect_workers": collect_workers, "collector": collector}
    changes["backend"] = backend
    changes |= options or {}
    if num_envs is not None:
        changes["num_envs"] = num_envs
    if version is not None:
        changes["version"] = version
    config = TrainConfig.from_dict(recipe or {}, changes)
    torch.manual_seed(config.run.seed)
    method = make_method(config, torch_device(device))
    stopwatch = harness.Stopwatch()
    time_collections(method, stopwatch, parts)
    try:
        for _ in range(warmup_iters):
            method.iterate()
        stopwatch.restart()
        frames, iterations, losses, elapsed = iterate_for(method, seconds)
    finally:
        method.close()
    collect_s = stopwatch.spent["collect"]
    result = {
        "frames_per_s": frames / elapsed,
        "iterations": iterations,
        "frames": frames,
        "frames_per_iteration": frames / iterations,
        "seconds": elapsed,
        "collect_s": collect_s,
        "learn_s": elapsed - collect_s,
        "num_envs": config.run.num_envs,
        "rollout_length": config.run.rollout_length,
    }
    if parts:
        result["parts_s"] = {part: stopwatch.spent.get(part, 0.0) for part in PART_LABELS}
    if "curriculum/obstacles" in losses:
        result["obstacles"] = int(losses["curriculum/obstacles"])
    return result


def run_label(method: str, collector: str, workers: int) -> str:
    """What the report calls ``method`` collected by ``collector``: the method's name alone when in-process."""
    return method if collector == "inprocess" else f"{method} [{collector} x{workers}]"


def summarise(rounds: list[dict[str, dict]], peer_rates: list[float] | None):
    """Per-round ratios frames/s over MiniWorld's steps/s of every method (:func:`harness.bracketed_ratios`), their
    medians, and the goals judged on ``meta``'s median (``None`` when they cannot be judged)."""
    if not peer_rates:
        return {}, {}, {goal: None for goal, _ in GOALS}
    per_round = {
        name: harness.bracketed_ratios([r[name]["frames_per_s"] for r in rounds], peer_rates) for name in rounds[0]
    }
    medians = {name: statistics.median(values) for name, values in per_round.items()}
    goals = {goal: (medians["meta"] >= multiple if "meta" in medians else None) for goal, multiple in GOALS}
    return per_round, medians, goals


def combine(results: list[dict]) -> dict:
    """One method's figures over its rounds: median frames/s, and the totals of iterations, frames and time (and of
    each part's time, with ``--parts``)."""
    total = {key: sum(r[key] for r in results) for key in ("iterations", "frames", "seconds", "collect_s", "learn_s")}
    if "parts_s" in results[0]:
        total["parts_s"] = {part: sum(r["parts_s"][part] for r in results) for part in results[0]["parts_s"]}
    return (
        results[-1]
        | total
        | {
            "frames_per_s": statistics.median(r["frames_per_s"] for r in results),
            "frames_per_s_rounds": [r["frames_per_s"] for r in results],
            "frames_per_iteration": total["frames"] / total["iterations"],
        }
    )


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command-line flags, every value checked."""
    from activeperc_env.rooms import ROOMS
    from activeperc_env.warp_backend import BACKENDS
    from activeperc_rl.collection import COLLECTORS
    from activeperc_rl.config import DEVICES
    from activeperc_rl.methods import METHODS
    from activeperc_rl.recipe import PRESETS, TrainConfig, preset

    PRESET_NAMES = sorted(path.stem for path in PRESETS.glob("*.yaml"))

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--methods", nargs="+", choices=METHODS, default=list(METHODS), metavar="METHOD", help=f"of {METHODS} (all)"
    )
    parser.add_argument(
        "--seconds",
        type=harness.at_least(float, "seconds", 0, strict=True),
        default=20.0,
        help="timed seconds per method and for MiniWorld (20)",
    )
    parser.add_argument(
        "--num-envs",
        type=harness.at_least(int, "num_envs", 1),
        default=None,
        help="rooms per environment (the TrainConfig default)",
    )
    parser.add_argument(
        "--threads",
        type=harness.at_least(int, "threads", 0),
        default=TrainConfig().run.torch_threads,
        help="torch threads while collecting, as run.torch_threads (0: torch's default; default: as training);"
        " learning runs on run.learner_threads (all usable CPUs), as in training",
    )
    parser.add_argument(
        "--device", choices=DEVICES, default="cpu", help="where the networks run: cpu (default), cuda, or auto"
    )
    parser.add_argument(
        "--workers",
        "--collect-workers",
        type=harness.at_least(int, "workers", 1),
        default=2,
        help="workers per env of the process and ray collectors (run.collect_workers; 2)",
    )
    parser.add_argument(
        "--collector",
        nargs="+",
        choices=("inprocess", *COLLECTORS),
        default=["inprocess"],
        help="where each method collects, each timed in turn: in this process (inprocess, default), TorchRL's"
        " multi-process collector (process) or its Ray collector on a local Ray instance (ray)",
    )
    parser.add_argument(
        "--backend",
        choices=BACKENDS,
        default="mujoco",
        help="the rooms' physics and renderer (TrainConfig.backend): mujoco (default) or warp (on --device)",
    )
    parser.add_argument(
        "--warmup-iters",
        type=harness.at_least(int, "warmup_iters", 0),
        default=2,
        help="untimed iterations before each timing (2)",
    )
    parser.add_argument(
        "--parts",
        action="store_true",
        help="also time the physics, renders, look, resets and network forward passes within each collection"
        " (inprocess only)",
    )
    parser.add_argument("--preset", choices=PRESET_NAMES, help="time activeperc-train's named preset (default: none)")
    parser.add_argument("--version", type=int, choices=tuple(ROOMS), help="time this room (default: the preset's)")
    parser.add_argument(
        "--flip",
        metavar="OPTION",
        help="also time each method with this true/false training option flipped (e.g. reuse_features), in the same"
        " rounds, and print the ratio",
    )
    parser.add_argument(
        "--variant",
        metavar="OPTION=VALUE",
        nargs="+",
        help="also time each method with these training options changed (e.g. num_envs=32 rollout_length=8), in the"
        " same rounds, and print the ratio",
    )
    harness.add_round_flags(parser, per="method")
    parser.add_argument("--json", action="store_true", help="also print one JSON object with every figure")
    parser.add_argument("--out", type=Path, help="also write that JSON object, with the command and date, to this file")
    args = parser.parse_args(argv)
    harness.refuse_unwritable(parser, {"--out": args.out})
    if args.parts and args.collector != ["inprocess"]:
        parser.error("--parts times the rooms of this process: it needs --collector inprocess")
    if args.flip is not None:
        config = TrainConfig.from_dict(preset(args.preset) if args.preset else {})
        sections = [section for section in config.to_dict().values() if isinstance(section, dict)]
        values = [section[args.flip] for section in sections if args.flip in section]
        if not values or not isinstance(values[0], bool):
            parser.error(f"--flip {args.flip}: not a true/false option of the training config")
        args.flip_value = not values[0]
    if args.flip is not None and args.variant:
        parser.error("--flip and --variant: one or the other")
    args.changed = {args.flip: args.flip_value} if args.flip is not None else variant(parser, args)
    return args


def variant(parser: argparse.ArgumentParser, args: argparse.Namespace) -> dict:
    """The options of ``--variant`` by name, their values read as YAML (``32``, ``linear``, ``false``), checked by
    building the config."""
    import yaml

    from activeperc_rl.recipe import TrainConfig, preset

    changed = {}
    for item in args.variant or []:
        name, equals, value = item.partition("=")
        if not equals or not name:
            parser.error(f"--variant {item!r}: expected OPTION=VALUE")
        changed[name] = yaml.safe_load(value)
    try:
        TrainConfig.from_dict(preset(args.preset) if args.preset else {}, changed)
    except ValueError as error:
        parser.error(f"--variant: {error}")
    return changed


def describe_machine(args: argparse.Namespace) -> dict:
    """:func:`harness.machine_info` with torch's version and threads (set from ``--threads``), the device, the GPU
    and the allocator as ``activeperc-train`` sets it."""
    import torch

    from activeperc_rl.runtime.allocator import keep_freed_memory

    if args.threads:
        torch.set_num_threads(args.threads)
    machine = harness.machine_info()
    machine |= {"torch": torch.__version__, "torch_threads": torch.get_num_threads(), "device": args.device}
    machine["keep_freed_memory"] = keep_freed_memory()  # as activeperc-train does
    if torch.cuda.is_available():
        machine["gpu"] = torch.cuda.get_device_name()
    return machine


def print_header(args: argparse.Namespace, machine: dict) -> None:
    """The report's first lines: what was timed, on what."""
    print("activeperc training speed vs MiniWorld")
    print(harness.machine_line(machine))
    print(f"         torch {machine['torch']} with {machine['torch_threads']} threads, Python {machine['python']}")
    print(f"         malloc keeps freed memory (activeperc_rl.runtime.allocator): {machine['keep_freed_memory']}")
    if "gpu" in machine:
        print(f"         GPU {machine['gpu']}")
    print(
        f"timing:  {args.seconds:g} s per method after {args.warmup_iters} untimed iterations,"
        f" networks on {args.device},"
        f" collectors {', '.join(args.collector)} ({args.workers} workers each but inprocess);"
        f" {args.rounds} round(s)"
        + ("" if args.no_peer else ", MiniWorld timed before the first and after each")
        + f"; recipe: {f'--preset {args.preset}' if args.preset else 'the defaults'}"
        + ("" if args.version is None else f", room v{args.version}")
    )
    print()


def print_run(label: str, result: dict) -> None:
    """The report's line on one run's frames/s, iterations and the collection's share of them."""
    collect = result["collect_s"] / result["seconds"]
    detail = (
        f"{result['iterations']} it x {result['frames_per_iteration']:g} frames"
        f" (N={result['num_envs']}, T={result['rollout_length']}),"
        f" collect {collect:.0%} / learn {1 - collect:.0%}"
    )
    if "obstacles" in result:
        detail += f", phase with {result['obstacles']} obstacles"
    print(f"train {label:<{WIDTH}}{result['frames_per_s']:9.1f} frames/s   {detail}")


def print_parts(label: str, result: dict) -> None:
    """The report's lines on where one run's collection time went (``--parts``): milliseconds per env step (one
    cycle of every room) in each part."""
    steps, collect = result["frames"] / result["num_envs"], result["collect_s"]
    print(f"parts {label}: collection {1e3 * collect / steps:.1f} ms per env step of {result['num_envs']} rooms")
    rows = [(PART_LABELS[part], spent) for part, spent in result["parts_s"].items()]
    rows.append(("the rest (TorchRL, tensordict, sampling)", collect - sum(result["parts_s"].values())))
    for name, spent in rows:
        print(f"  {name:<40}{1e3 * spent / steps:7.2f} ms per step  ({spent / collect:4.0%})")


def print_iteration(label: str, result: dict) -> None:
    """The report's line on one run's mean iteration: its milliseconds, collection's and learning's."""
    per_it = result["seconds"] / result["iterations"]
    collect = result["collect_s"] / result["iterations"]
    print(
        f"iter  {label:<{WIDTH}}{per_it * 1e3:.0f} ms = collect {collect * 1e3:.0f} ms"
        f" ({collect / per_it:.0%}) + learn {(per_it - collect) * 1e3:.0f} ms ({1 - collect / per_it:.0%})"
    )


def options_label(options: dict) -> str:
    """What a run's label adds for its changed ``options``: `` [name=value]`` each."""
    return "".join(f" [{k}={v}]" for k, v in options.items())


def print_gain(name: str, label: str, rounds: list[dict[str, dict]]) -> None:
    """The report's line on how much faster the run ``label`` trained than the run ``name`` (a method in this process,
    or with ``--flip`` or ``--variant`` the run with options changed), round by round."""
    gain = [r[label]["frames_per_s"] / r[name]["frames_per_s"] for r in rounds]
    print(f"gain  {label:<{WIDTH}}{harness.spread(gain, 2, 'x')} the frames/s of {name}")


def print_ratios(per_round: dict, goals: dict, cpus: int) -> None:
    """The report's ratios frames/s over MiniWorld's steps/s, every round's, and the goals judged on ``meta``'s."""
    if per_round:
        print("ratio frames/s over MiniWorld's raw steps/s, each round over the MiniWorld figures around it:")
        for name, values in per_round.items():
            print(f"ratio {name:<{WIDTH}}{harness.spread(values, 2, 'x')}")
    else:
        print("ratios: unknown, MiniWorld was not measured")
    for (goal, multiple), met in zip(GOALS, goals.values(), strict=True):
        print(f"goal  {goal}: {harness.verdict(met, per_round.get('meta'), multiple, cpus)}")


def main(argv: list[str] | None = None) -> dict:
    """Parse the flags, train every method for a while, measure MiniWorld, print the report; return the JSON
    report."""
    args = parse_args(argv)
    import activeperc_env  # noqa: F401 (chooses the GL backend, e.g. MUJOCO_GL=egl, before we report it)
    from activeperc_rl.envs import torch_device
    from activeperc_rl.recipe import preset

    machine = describe_machine(args)
    print_header(args, machine)
    runs = [(name, collector, {}) for name in args.methods for collector in args.collector]
    if args.changed:
        runs = [run for name, collector, _ in runs for run in ((name, collector, {}), (name, collector, args.changed))]

    def measure(i: int) -> dict[str, dict]:
        results = {}
        for name, collector, options in runs:
            label = run_label(name, collector, args.workers) + options_label(options)
            workers, kind = (0, "process") if collector == "inprocess" else (args.workers, collector)
            results[label] = bench_method(
                name,
                args.num_envs,
                args.seconds,
                args.warmup_iters,
                args.device,
                workers,
                kind,
                args.parts,
                args.backend,
                preset(args.preset) if args.preset else None,
                args.version,
                options,
            )
            print(f"round {i + 1}: train {label:<{WIDTH}}{results[label]['frames_per_s']:9.1f} frames/s", flush=True)
            gc.collect()
        return results

    measured = peer.in_rounds(args.rounds, measure, args.seconds, 1.0, 0, args.peer_lp_threads, skip=args.no_peer)
    rounds, peer_rates = measured.ours, measured.peer
    ours = {label: combine([r[label] for r in rounds]) for label in rounds[0]}
    print()

    print(f"figures: {harness.of_rounds(args.rounds)}")
    for label, result in ours.items():
        print_run(label, result)
    print(peer.describe(measured))
    print()

    for label, result in ours.items():
        print_iteration(label, result)
        if args.parts:
            print_parts(label, result)
    for name, collector, options in runs:
        if collector != "inprocess" and name in ours and not options:
            print_gain(name, run_label(name, collector, args.workers), rounds)
        if options:  # the gain of the default over a flipped option, of a variant over the default
            label = run_label(name, collector, args.workers)
            changed = label + options_label(options)
            if args.flip is not None:
                print_gain(changed, label, rounds)
            else:
                print_gain(label, changed, rounds)
    per_round, ratios, goals = summarise(rounds, peer_rates)
    print_ratios(per_round, goals, machine["usable_cpus"])

    if "gpu" in machine and "meta" in ours and torch_device(args.device).type == "cuda":
        met = ours["meta"]["frames_per_s"] >= GPU_GOAL
        verdict = "MET" if met else "NOT MET"
        print(f"goal  meta >= {GPU_GOAL:,} frames/s on an H100: {verdict} on {machine['gpu']}")

    report = {
        "machine": machine,
        "seconds": args.seconds,
        "warmup_iters": args.warmup_iters,
        "rounds": args.rounds,
        "methods": ours,
        **measured.report(),
        "ratio_rounds": per_round,
        "ratios": ratios,
        "goals_met": goals,
    }
    if args.json:
        print(json.dumps(report))
    if args.out is not None:
        command = " ".join(["python benchmarks/train_speed.py", *(sys.argv[1:] if argv is None else argv)])
        saved = report | {"command": command, "cpu": portable.machine(), "date": time.strftime("%Y-%m-%d")}
        with atomic_path(args.out) as temporary:
            temporary.write_text(json.dumps(saved, indent=1) + "\n")
    return report


if __name__ == "__main__":
    main()
