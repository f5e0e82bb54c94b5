"""Throughput of the batched TorchRL env against its number of rooms, and its memory over many episodes.

Each rate is set over MiniWorld's raw steps/s, with the bare ``Simulator`` beside it at N = 64.

Run it from the repository root (MiniWorld comes with the ``bench`` extra)::

    python benchmarks/env_scaling.py                                   # 5 s per N, 3 rounds, no memory run
    python benchmarks/env_scaling.py --num-envs 16 64 --seconds 2 --rounds 1 --json
    python benchmarks/env_scaling.py --num-envs 64 --memory-episodes 10000 --memory-csv /tmp/memory.csv
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import statistics
import time
from pathlib import Path

import harness
import peer

DEFAULT_NUM_ENVS = (1, 4, 16, 64, 256, 1024)
GOAL_NUM_ENVS = 64  # the goal is judged at this number of rooms
GOAL_MULTIPLE = 5.0  # ... which must reach this multiple of MiniWorld's raw steps/s
FLAT_TOLERANCE = 0.05  # memory is "flat" when its maximum stays within this fraction of the start RSS
MEMORY_SAMPLES = 100  # about this many RSS samples over a memory run
CSV_COLUMNS = ("num_envs", "cycles_per_s", "miniworld_steps_per_s", "ratio")


def rss_mib() -> float:
    """The resident memory of this process in MiB, read from ``/proc/self/statm`` (Linux)."""
    with open("/proc/self/statm") as statm:
        resident_pages = int(statm.read().split()[1])
    return resident_pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def bench_rooms(
    num_envs: int, seconds: float, warmup: float, seed: int, backend: str = "mujoco", device: str = "cpu"
) -> float:
    """Cycles/s of :class:`harness.RandomRooms` with ``num_envs`` rooms, summed over the rooms."""
    rooms = harness.RandomRooms(num_envs, seed, backend, device)

    def step() -> int:
        rooms.cycle()
        return num_envs

    try:
        return harness.timed_rate(step, seconds, warmup)
    finally:
        rooms.close()


def core_split(num_envs: int, seconds: float, warmup: float, seed: int) -> dict[str, float]:
    """Where a cycle of the bare ``Simulator(num_envs)`` (:func:`harness.core_cycle`) spends its time: seconds per
    cycle in each method of :data:`harness.SIMULATOR_PARTS`; and ``cycles_per_s``, summed over the rooms, for
    comparison with the TorchRL env at the same N."""
    sim, rng = harness.random_core(num_envs, seed)
    try:
        rate, per_cycle = harness.timed_core(sim, rng, seconds, warmup)
    finally:
        sim.close()
    return per_cycle | {"cycles_per_s": rate * num_envs}


def measure_memory(episodes: int, num_envs: int, warmup: float, seed: int) -> dict:
    """Step :class:`harness.RandomRooms` for ``warmup`` seconds, then until ``episodes`` episodes ended; sample the RSS.

    Returns ``samples`` (``(episodes ended, RSS MiB)`` pairs, the first after the warm-up, the last at the end),
    ``start_mib``, ``end_mib``, ``max_mib``, ``growth_mib`` (end - start), ``max_growth_mib`` (max - start),
    ``flat`` (``max_growth_mib`` below ``tolerance``, :data:`FLAT_TOLERANCE`, of the start), ``episodes`` (ended,
    at least the number asked for), ``num_envs`` and ``cycles`` (after the warm-up).
    """
    rooms = harness.RandomRooms(num_envs, seed)
    try:
        deadline = time.perf_counter() + warmup
        while time.perf_counter() < deadline:  # the warm-up: its episodes are not counted
            rooms.cycle()
        gc.collect()
        samples = [(0, rss_mib())]
        every = max(1, episodes // MEMORY_SAMPLES)
        ended, cycles = 0, 0
        while ended < episodes:
            ended += rooms.cycle()
            cycles += 1
            if ended >= samples[-1][0] + every or ended >= episodes:
                samples.append((ended, rss_mib()))
    finally:
        rooms.close()
    start, end = samples[0][1], samples[-1][1]
    peak = max(rss for _, rss in samples)
    return {
        "episodes": ended,
        "num_envs": num_envs,
        "cycles": cycles,
        "start_mib": start,
        "end_mib": end,
        "max_mib": peak,
        "growth_mib": end - start,
        "max_growth_mib": peak - start,
        "tolerance": FLAT_TOLERANCE,
        "flat": peak - start < FLAT_TOLERANCE * start,
        "samples": samples,
    }


def plot_scaling(path: Path, rates: dict[int, float], peer_rate: float | None, cpus: int) -> None:
    """Plot cycles/s against the number of rooms (log x) with MiniWorld's steps/s and 5x that, to ``path``."""
    import matplotlib

    from activeperc_rl.runtime.atomic import atomic_path

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    sizes = sorted(rates)
    ax.plot(sizes, [rates[n] for n in sizes], "o-", label="ours: make_env(num_envs=N), looker mode")
    if peer_rate:
        ax.axhline(peer_rate, color="tab:red", linestyle="--", label=f"MiniWorld {peer.PEER_ENV} raw steps/s")
        ax.axhline(GOAL_MULTIPLE * peer_rate, color="tab:green", linestyle=":", label=f"{GOAL_MULTIPLE:g}x MiniWorld")
    ax.set_xscale("log", base=2)
    ax.set_xticks(sizes, [str(n) for n in sizes])
    ax.set_ylim(bottom=0)
    ax.set_xlabel("rooms N (num_envs)")
    ax.set_ylabel("cycles/s, summed over rooms")
    ax.set_title(f"Batched env throughput vs rooms ({cpus} CPU{'s' if cpus != 1 else ''})")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    fig.tight_layout()
    with atomic_path(path) as temporary:
        fig.savefig(temporary, format=path.suffix[1:] or "png", dpi=120)
    plt.close(fig)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command-line flags, every value checked."""
    from activeperc_env.warp_backend import BACKENDS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--num-envs",
        nargs="+",
        type=harness.at_least(int, "num_envs", 1),
        default=list(DEFAULT_NUM_ENVS),
        metavar="N",
        help=f"numbers of rooms to time ({' '.join(map(str, DEFAULT_NUM_ENVS))})",
    )
    harness.add_timing_flags(parser, seconds=5.0, warmup=1.0, per="N")
    parser.add_argument(
        "--memory-episodes",
        type=harness.at_least(int, "memory_episodes", 0),
        default=0,
        metavar="E",
        help="memory mode: run until E episodes ended and sample the RSS (0: off; the issue asks for 10000)",
    )
    parser.add_argument(
        "--memory-rooms", type=harness.at_least(int, "memory_rooms", 1), default=16, help="rooms of the memory run (16)"
    )
    parser.add_argument(
        "--backend", choices=BACKENDS, default="mujoco", help="the rooms' physics and renderer (mujoco)"
    )
    parser.add_argument(
        "--device", default="cpu", help="where the observations live, and the warp backend runs: cpu or cuda (cpu)"
    )
    parser.add_argument("--csv", type=Path, help="write the rates to this CSV (default: none)")
    parser.add_argument("--plot", type=Path, help="write the plot to this image (default: none)")
    parser.add_argument("--memory-csv", type=Path, help="write the RSS samples to this CSV (default: none)")
    parser.add_argument("--json", action="store_true", help="also print one JSON object with every figure")
    args = parser.parse_args(argv)
    harness.refuse_unwritable(parser, {"--csv": args.csv, "--plot": args.plot, "--memory-csv": args.memory_csv})
    return args


def print_memory(memory: dict) -> None:
    """The report's lines on :func:`measure_memory`'s run."""
    print(
        f"memory make_env(num_envs={memory['num_envs']}), {memory['episodes']} episodes in {memory['cycles']}"
        f" cycles: RSS start {memory['start_mib']:.1f} MiB (after warm-up), end {memory['end_mib']:.1f} MiB,"
        f" max {memory['max_mib']:.1f} MiB"
    )
    state = "flat" if memory["flat"] else "NOT flat"
    print(
        f"memory growth {memory['growth_mib']:+.1f} MiB at the end, {memory['max_growth_mib']:+.1f} MiB at the max:"
        f" {state} (tolerance {FLAT_TOLERANCE:.0%} of the start RSS)"
    )


def split_summary(rounds: list[dict[int, float]], splits: list[dict[str, float]]) -> dict:
    """The medians of :func:`core_split`'s rounds, and how many seconds more a cycle of the TorchRL env took than one
    of the bare simulator in each round (``torchrl_overhead_rounds``) and in the median (``torchrl_overhead``)."""
    split = {part: statistics.median(s[part] for s in splits) for part in splits[0]}
    extra = [
        GOAL_NUM_ENVS / r[GOAL_NUM_ENVS] - GOAL_NUM_ENVS / s["cycles_per_s"]
        for r, s in zip(rounds, splits, strict=True)
    ]
    return split | {"torchrl_overhead": statistics.median(extra), "torchrl_overhead_rounds": extra}


def print_split(split: dict) -> None:
    """The report's lines on :func:`split_summary`."""
    alone = f"split Simulator(num_envs={GOAL_NUM_ENVS}) alone: {split['cycles_per_s']:.1f} cycles/s"
    parts = ", ".join(f"{label} {1e3 * split[part]:.1f} ms" for part, label in harness.SIMULATOR_PARTS.items())
    print(f"{alone}; per cycle: {parts}")
    extra = harness.spread([1e3 * value for value in split["torchrl_overhead_rounds"]], 1, " ms")
    print(f"split TorchRL env at N={GOAL_NUM_ENVS} minus the bare simulator, same round: {extra} per cycle")


def main(argv: list[str] | None = None) -> dict:
    """Parse the flags, time every N, measure MiniWorld and the memory, print the report; return the JSON report."""
    args = parse_args(argv)
    import activeperc_env  # noqa: F401 (chooses the GL backend, e.g. MUJOCO_GL=egl, before we report it)

    machine = harness.machine_info()
    print("activeperc batched env throughput vs rooms")
    print(harness.machine_line(machine))
    print(
        f"timing:  {args.seconds:g} s per N after {args.warmup:g} s warm-up, seed {args.seed}, random actions;"
        f" {args.rounds} round(s)" + ("" if args.no_peer else ", MiniWorld timed before the first and after each")
    )
    print()

    # the memory run comes first, so that no larger env has raised the RSS it starts from
    memory = None
    if args.memory_episodes:
        memory = measure_memory(args.memory_episodes, args.memory_rooms, args.warmup, args.seed)
        print_memory(memory)
        if args.memory_csv:
            harness.write_csv(args.memory_csv, ("episodes", "rss_mib"), memory["samples"])
            print(f"wrote {args.memory_csv}")
        print()
        gc.collect()

    splits = []  # the bare simulator at N = GOAL_NUM_ENVS, timed in each round right after the TorchRL env

    def measure(i: int) -> dict[int, float]:
        rates = {}
        for n in dict.fromkeys(args.num_envs):  # in the order given, each N once
            rates[n] = bench_rooms(n, args.seconds, args.warmup, args.seed, args.backend, args.device)
            print(f"round {i + 1}: make_env(num_envs={n}) {rates[n]:.1f} cycles/s", flush=True)
            gc.collect()
            if n == GOAL_NUM_ENVS:
                splits.append(core_split(n, args.seconds, args.warmup, args.seed))
                alone = splits[-1]["cycles_per_s"]
                print(f"round {i + 1}: Simulator(num_envs={n}) alone {alone:.1f} cycles/s", flush=True)
                gc.collect()
        return rates

    measured = peer.in_rounds(
        args.rounds, measure, args.seconds, args.warmup, args.seed, args.peer_lp_threads, skip=args.no_peer
    )
    rounds = measured.ours
    print()

    rates = {n: statistics.median(r[n] for r in rounds) for n in rounds[0]}
    print(f"figures: {harness.of_rounds(args.rounds)}")
    for n, rate in rates.items():
        print(f"ours  make_env(num_envs={n:<5}) {rate:10.1f} cycles/s   ({rate / n:7.1f} per room)")
    peer_rate = statistics.median(measured.peer) if measured.peer else None
    print(peer.describe(measured, width=30))
    print()

    per_round = (
        {n: harness.bracketed_ratios([r[n] for r in rounds], measured.peer) for n in rates} if measured.peer else {}
    )
    ratios = {n: statistics.median(values) for n, values in per_round.items()}
    for n, values in per_round.items():
        print(f"ratio N={n:<5} {harness.spread(values, 2, 'x')} MiniWorld raw steps/s")
    goal = f"N={GOAL_NUM_ENVS} >= {GOAL_MULTIPLE:g}x MiniWorld raw env speed on 2 cores"
    met = ratios[GOAL_NUM_ENVS] >= GOAL_MULTIPLE if GOAL_NUM_ENVS in ratios else None
    verdict = harness.verdict(met, per_round.get(GOAL_NUM_ENVS), GOAL_MULTIPLE, machine["usable_cpus"])
    if met is None:
        verdict += " (MiniWorld not measured)" if not peer_rate else f" (N={GOAL_NUM_ENVS} not timed)"
    print(f"goal  {goal}: {verdict}")

    split = None
    if splits:
        split = split_summary(rounds, splits)
        print()
        print_split(split)

    rows = [(n, rate, peer_rate, ratios.get(n)) for n, rate in rates.items()]
    if args.csv:
        harness.write_csv(args.csv, CSV_COLUMNS, rows)
        print(f"wrote {args.csv}")
    if args.plot:
        plot_scaling(args.plot, rates, peer_rate, machine["usable_cpus"])
        print(f"wrote {args.plot}")

    report = {
        "machine": machine,
        "seconds": args.seconds,
        "warmup": args.warmup,
        "seed": args.seed,
        "cycles_per_s": rates,
        "rounds": rounds,
        **measured.report(),
        "ratio_rounds": per_round,
        "ratios": ratios,
        "goal": goal,
        "goal_met": met,
        "core_split_s_per_cycle": split,
        "core_split_rounds": splits,
        "memory": memory,
        "csv": str(args.csv),
        "plot": str(args.plot),
        "memory_csv": str(args.memory_csv) if memory else None,
    }
    if args.json:
        print(json.dumps(report))
    return report


if __name__ == "__main__":
    main()
