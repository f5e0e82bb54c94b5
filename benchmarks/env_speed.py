"""Speed of the room's APIs against MiniWorld's raw steps/s, measured in one run.

The PettingZoo AEC env (and where its cycle's time goes), the batched core ``Simulator`` and Gymnasium's vector envs.

Run it from the repository root (MiniWorld comes with the ``bench`` extra)::

    python benchmarks/env_speed.py              # 5 s per measurement, 3 rounds (about 3 minutes)
    python benchmarks/env_speed.py --versions 1 3 --seconds 3
    python benchmarks/env_speed.py --seconds 2 --rounds 1 --json
"""

from __future__ import annotations

import argparse
import json
import statistics

import harness
import peer

from activeperc_env.rooms import DEFAULT, ROOMS

CORE_SIZES = (1, 16, 64)
GYM_VEC_SIZE = 16  # rooms of the Gymnasium vector envs
GOALS = (  # (figure, the multiple of MiniWorld's steps/s it must reach, the goal's name)
    ("aec", 1.0, "aec >= 1x MiniWorld"),
    ("core_n64", 3.0, "core N=64 >= 3x MiniWorld"),
)


def gl_renderer_name(sim) -> str:
    """The renderer string of ``sim``'s GL context (e.g. llvmpipe), or '?' when it cannot be read."""
    try:
        from OpenGL import GL

        with sim.renderer._current():  # the context is current only while a renderer draws
            return GL.glGetString(GL.GL_RENDERER).decode()
    except Exception:  # only informative
        return "?"


def random_aec(seed: int, version: int = 1):
    """The PettingZoo AEC env of room ``version`` reset from ``seed``, and one random-action cycle of it (``cycle() ->
    1``): the mover's ``last()`` and step, then the looker's, as PettingZoo's loop makes them (each step gives one
    80x60 view; the mover's is drawn only when the look turned the camera); the env is reset when an episode ends."""
    import activeperc_env

    env = activeperc_env.env(version=version)
    env.reset(seed=seed)
    for i, agent in enumerate(env.possible_agents):
        env.action_space(agent).seed(seed + i)

    def cycle() -> int:
        for agent in env.possible_agents:  # the mover, then the looker
            env.last()  # what a PettingZoo loop reads before each step (the observation is copied)
            env.step(env.action_space(agent).sample())
        if any(env.terminations.values()) or any(env.truncations.values()):
            env.reset()  # unseeded: continues the seeded stream
        return 1

    return env, cycle


def bench_aec(seconds: float, warmup: float, seed: int, version: int = 1) -> tuple[float, str]:
    """Cycles/s of the PettingZoo AEC env with random actions; also returns the GL renderer's name."""
    env, cycle = random_aec(seed, version)
    gl_renderer = gl_renderer_name(env.unwrapped.sim)
    try:
        return harness.timed_rate(cycle, seconds, warmup), gl_renderer
    finally:
        env.close()


def aec_breakdown(seconds: float, warmup: float, seed: int, version: int = 1) -> dict[str, float]:
    """Where an AEC cycle's time goes: milliseconds per cycle in each method of :data:`harness.SIMULATOR_PARTS`, in
    ``"rest"`` (PettingZoo's API, action checks, observation dicts, drawing the random actions) and in all,
    ``"total"``.

    The same random cycles as :func:`bench_aec`, timed again apart from it so that the timers do not touch its rate:
    the env's own simulator gets timing wrappers on its methods (instance attributes; the class is untouched).
    """
    env, cycle = random_aec(seed, version)
    stopwatch = harness.Stopwatch()
    try:
        with stopwatch.watching(env.unwrapped.sim, harness.SIMULATOR_PARTS):
            rate, per_cycle = harness.timed_parts(cycle, seconds, warmup, stopwatch)
    finally:
        env.close()
    result = {part: 1e3 * spent for part, spent in per_cycle.items()}
    result["total"] = 1e3 / rate
    result["rest"] = result["total"] - sum(per_cycle.values()) * 1e3
    return result


def bench_core(num_envs: int, seconds: float, warmup: float, seed: int, version: int = 1) -> float:
    """Cycles/s of ``Simulator(num_envs)`` with random actions (:func:`harness.core_cycle`: up to 2 renders a cycle),
    summed over its rooms."""
    sim, rng = harness.random_core(num_envs, seed, version)

    def cycle() -> int:
        harness.core_cycle(sim, rng)
        return num_envs

    try:
        return harness.timed_rate(cycle, seconds, warmup)
    finally:
        sim.close()


def bench_gym_vector(mode: str, seconds: float, warmup: float, seed: int, version: int = 1) -> float:
    """Steps/s, summed over the rooms, of ``gymnasium.make_vec("activeperc/Joint-vVERSION", 16)`` in ``mode``
    (``"vector_entry_point"``: ours; ``"sync"``: Gymnasium's ``SyncVectorEnv``), random actions."""
    import gymnasium
    import numpy as np

    env_id = f"activeperc/Joint-v{version}"
    env = gymnasium.make_vec(env_id, num_envs=GYM_VEC_SIZE, vectorization_mode=mode)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    ended = np.zeros(GYM_VEC_SIZE, dtype=bool)

    def step() -> int:
        _, _, terminated, truncated, _ = env.step(rng.integers(9, size=GYM_VEC_SIZE))
        stepped = GYM_VEC_SIZE - int(ended.sum())  # both modes only reset the rooms that ended at the last step
        ended[:] = terminated | truncated
        return stepped

    try:
        return harness.timed_rate(step, seconds, warmup)
    finally:
        env.close()


FIGURES = {  # key of each figure of ours: its label and unit
    "aec": ("AEC env activeperc_env.env()", "cycles/s"),
    **{f"core_n{n}": (f"core Simulator(num_envs={n})", "cycles/s   (up to 2 renders each)") for n in CORE_SIZES},
    f"gym_vector_n{GYM_VEC_SIZE}": (f"make_vec Joint N={GYM_VEC_SIZE}", "steps/s    (1 render each)"),
    f"gym_sync_n{GYM_VEC_SIZE}": (f"make_vec Joint, mode sync N={GYM_VEC_SIZE}", "steps/s    (1 render each)"),
}


def measure_round(
    seconds: float, warmup: float, seed: int, version: int = 1
) -> tuple[dict[str, float], dict[str, float], str]:
    """One round of every figure of ours (:data:`FIGURES`) in room ``version`` and of the AEC cycle's breakdown
    (:func:`aec_breakdown`); also returns the GL renderer's name."""
    ours = {}
    ours["aec"], gl_renderer = bench_aec(seconds, warmup, seed, version)
    aec_parts = aec_breakdown(seconds, warmup, seed, version)
    for n in CORE_SIZES:
        ours[f"core_n{n}"] = bench_core(n, seconds, warmup, seed, version)
    for mode, key in (("vector_entry_point", "gym_vector"), ("sync", "gym_sync")):
        ours[f"{key}_n{GYM_VEC_SIZE}"] = bench_gym_vector(mode, seconds, warmup, seed, version)
    return ours, aec_parts, gl_renderer


def summarise(rounds: list[dict[str, float]], peer_rates: list[float] | None, versions=(1,)):
    """Per-round ratios ours/MiniWorld (:func:`harness.bracketed_ratios`) of every figure (keys ``FIGURE_vVERSION``),
    their medians, and the two goals of each room version judged on the medians (all empty when MiniWorld was not
    measured)."""
    if not peer_rates:
        return {}, {}, {}
    per_round = {key: harness.bracketed_ratios([r[key] for r in rounds], peer_rates) for key in rounds[0]}
    medians = {key: statistics.median(values) for key, values in per_round.items()}
    goals = {f"v{v} {name}": medians[f"{key}_v{v}"] >= multiple for v in versions for key, multiple, name in GOALS}
    return per_round, medians, goals


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command-line flags, every value checked."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.add_timing_flags(parser, seconds=5.0, warmup=1.0, per="figure")
    parser.add_argument(
        "--versions",
        type=int,
        nargs="+",
        choices=sorted(ROOMS),
        default=[DEFAULT],
        help=f"room versions, each in every round (the default room, {DEFAULT})",
    )
    parser.add_argument("--json", action="store_true", help="also print one JSON object with every figure")
    return parser.parse_args(argv)


def print_header(args: argparse.Namespace, machine: dict) -> None:
    """The report's first lines: what was timed, on what."""
    print("activeperc env speed vs MiniWorld")
    print(harness.machine_line(machine))
    print(f"         {machine['platform']}, Python {machine['python']}")
    print(
        f"timing:  {args.seconds:g} s per measurement after {args.warmup:g} s warm-up, seed {args.seed};"
        f" {args.rounds} round(s) of ours (room version {', '.join(map(str, args.versions))} in each)"
        + ("" if args.no_peer else ", MiniWorld timed before the first and after each")
    )
    print()


def print_breakdown(version: int, parts: dict[str, float]) -> None:
    """The report's line on where an AEC cycle of room ``version`` goes (:func:`aec_breakdown`'s medians)."""
    named = " + ".join(f"{label} {parts[part]:.2f}" for part, label in harness.SIMULATOR_PARTS.items())
    rest = f"the rest (PettingZoo API, checks, observation dicts, random actions) {parts['rest']:.2f}"
    print(f"where a v{version} AEC cycle goes (timed apart, medians): {parts['total']:.2f} ms = {named} + {rest}")


def print_ratios(per_round: dict, goals: dict, versions: list[int], cpus: int) -> None:
    """The report's ratios ours/MiniWorld, every round's, and the goals judged on their medians."""
    if not per_round:
        print("ratios and goals: unknown, MiniWorld was not measured")
        return
    print("ratio ours/MiniWorld, each round over the MiniWorld figures around it: median (rounds)")
    for key, values in per_round.items():
        print(f"ratio {key:<19}{harness.spread(values, 2, 'x')}")
    for version in versions:
        for key, multiple, name in GOALS:
            met = goals[f"v{version} {name}"]
            print(f"goal  v{version} {name}: {harness.verdict(met, per_round[f'{key}_v{version}'], multiple, cpus)}")


def main(argv: list[str] | None = None) -> dict:
    """Parse the flags, time ours and MiniWorld in alternation, print the report; return the JSON report."""
    args = parse_args(argv)
    import activeperc_env  # noqa: F401 (chooses the GL backend, e.g. MUJOCO_GL=egl, before we report it)

    machine = harness.machine_info()
    print_header(args, machine)
    breakdowns = {version: [] for version in args.versions}

    def measure(i: int) -> dict[str, float]:
        ours = {}
        for version in args.versions:
            figures, aec_parts, machine["gl_renderer"] = measure_round(args.seconds, args.warmup, args.seed, version)
            breakdowns[version].append(aec_parts)
            ours |= {f"{key}_v{version}": rate for key, rate in figures.items()}
        print(f"round {i + 1}: " + ", ".join(f"{key} {rate:.1f}" for key, rate in ours.items()), flush=True)
        return ours

    measured = peer.in_rounds(
        args.rounds, measure, args.seconds, args.warmup, args.seed, args.peer_lp_threads, skip=args.no_peer
    )
    rounds, peer_rates = measured.ours, measured.peer
    print()

    medians = {key: statistics.median(r[key] for r in rounds) for key in rounds[0]}
    gl = f"GL: {machine['gl_renderer']}, LP_NUM_THREADS: {machine['lp_num_threads']}"
    print(f"figures: {harness.of_rounds(args.rounds)}; {gl}")
    for version in args.versions:
        for key, (label, unit) in FIGURES.items():
            print(f"ours  v{version} {label:<34}{medians[f'{key}_v{version}']:9.1f} {unit}")
    print(peer.describe(measured))
    print()

    aec_parts = {
        version: {part: statistics.median(b[part] for b in breakdowns[version]) for part in breakdowns[version][0]}
        for version in args.versions
    }
    for version, parts in aec_parts.items():
        print_breakdown(version, parts)
    if peer_rates:
        print(f"a MiniWorld step: {1e3 / statistics.median(peer_rates):.2f} ms")
    print()

    per_round, ratios, goals = summarise(rounds, peer_rates, args.versions)
    print_ratios(per_round, goals, args.versions, machine["usable_cpus"])
    report = {
        "machine": machine,
        "seconds": args.seconds,
        "warmup": args.warmup,
        "seed": args.seed,
        "versions": args.versions,
        "rounds": rounds,
        "ours_cycles_per_s": medians,
        "aec_ms_per_cycle": aec_parts,
        "aec_ms_per_cycle_rounds": breakdowns,
        **measured.report(),
        "ratio_rounds": per_round,
        "ratios": ratios,
        "goals_met": goals,
    }
    if args.json:
        print(json.dumps(report))
    return report


if __name__ == "__main__":
    main()
