"""What a cheaper scene would buy: the env's speed goals against fewer physics steps and a plain floor, in one run.

The 2-core goals (the AEC env at least 1x MiniWorld, the core at N=64 at least 3x; ``make_env(num_envs=64)``, which
wraps the core, at least 5x) are not met by the scene as shipped: a cycle is 40 MuJoCo steps of 5 ms (one 5-Hz
control period) and up to two 80x60 views. This script asks how much of a cycle's physics and drawing would have to
go for them to be met on this machine. It times the AEC env ``activeperc_env.env()`` and the core
``Simulator(num_envs=64)`` with random actions (the cycles of ``env_speed.py``) for every pair of

- physics steps per cycle: 40 (as shipped), 20, 10, 5, 1, each a 5-ms step (a step costs about the same at any
  length, so this is the cost of a control period of that many steps; fewer steps of 5 ms move the robot less);
- floor: ``checker`` (as shipped) or ``plain``, drawn in the checker's mean colour without its texture.

Fewer steps per 5-Hz period need a longer step, which this robot's dynamics do not take: the script first prints
one move from rest with steps of 5, 10 and 20 ms (0.2 s of driving each; ``experiments/motion_profile.py``'s first
cycle). The variants change the compiled model and the physics steps per cycle inside this process only
(``activeperc_env.core.load_model`` and ``physics_steps`` are replaced while a variant is timed): none of them is
an option of the env.

MiniWorld ``MiniWorld-OneRoom-v0`` (80x60, raw ``env.step``, ``peer.py``) is timed before the first round and after
each, every round's figures are divided by the mean of the two MiniWorld figures around it, and the goals are
judged on the median ratio. In each round it also trains ``meta`` (``TrainConfig`` defaults, as
``train_speed.py`` does) for ``--train-seconds`` with the shipped scene and with the cheapest cycle (plain floor,
1 step): the training goals (at least 1x MiniWorld, issue 3; 1.5x, issue 4) against a cycle with next to no
physics. Run it from the repository root (``pip install -e .[train,bench]``)::

    python benchmarks/scene_cost.py                  # 3 s per figure, 3 rounds (about 8 minutes)
    python benchmarks/scene_cost.py --seconds 1 --rounds 1 --train-seconds 0
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
from collections.abc import Iterator
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "experiments")]  # env_speed.py, peer.py; motion_profile.py

import env_speed  # noqa: E402 (needs the path above)
import motion_profile  # noqa: E402
import peer  # noqa: E402
import train_speed  # noqa: E402

CORE_ROOMS = 64
STEPS = (40, 20, 10, 5, 1)  # physics steps of 5 ms per cycle; 40 as shipped
FLOORS = ("checker", "plain")  # as shipped; without its texture
MOTION_TIMESTEPS = (0.005, 0.010, 0.020)  # seconds of one physics step, for the moves from rest
GOALS = {  # (figure, the multiple of MiniWorld's steps/s it must reach): the goal's name
    ("aec", 1.0): "AEC env >= 1x",
    ("core_n64", 3.0): "core N=64 >= 3x",
    ("core_n64", 5.0): "core N=64 >= 5x (bounds make_env N=64's 5x goal)",
    ("meta", 1.0): "meta training >= 1x",
    ("meta", 1.5): "meta training >= 1.5x",
}
TRAIN_VARIANTS = (("checker", 40), ("plain", 1))  # as shipped; the cheapest cycle


@contextlib.contextmanager
def scene_variant(floor: str = "checker", steps: int | None = None, timestep: float = 0.005) -> Iterator[None]:
    """Within the block, every ``Simulator`` built (also inside ``activeperc_env.env()``) draws ``floor``, steps
    physics with ``timestep`` and takes ``steps`` of them per cycle (``None``: one control period's worth)."""
    import mujoco

    from activeperc_env import core

    load_model, physics_steps = core.load_model, core.physics_steps

    def load(config):
        model = load_model(config)
        model.opt.timestep = timestep
        if floor == "plain":
            material = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_MATERIAL, "floor")
            texture = model.mat_texid[material, mujoco.mjtTextureRole.mjTEXROLE_RGB]
            channels = int(model.tex_nchannel[texture])
            size = int(model.tex_width[texture] * model.tex_height[texture]) * channels
            texels = model.tex_data[model.tex_adr[texture] : model.tex_adr[texture] + size].reshape(-1, channels)
            model.mat_rgba[material, :3] = texels[:, :3].mean(axis=0) / 255
            model.mat_texid[material] = -1
        return model

    def steps_per_cycle(control_hz: float) -> int:
        return steps if steps is not None else max(1, round(1.0 / (control_hz * timestep)))

    core.load_model, core.physics_steps = load, steps_per_cycle
    try:
        yield
    finally:
        core.load_model, core.physics_steps = load_model, physics_steps


def first_moves() -> tuple[float, float]:
    """Degrees turned by one 'turn left' and metres driven by one 'forward', each from rest in an empty room
    (``experiments/motion_profile.py``'s first cycle)."""
    (_, turn), (forward, _) = (motion_profile.profile(action, cycles=1, seed=0)[0] for action in (0, 2))
    return turn, forward


def measure_round(seconds: float, warmup: float, seed: int, train_seconds: float) -> dict[tuple[str, int], dict]:
    """One round: for every (floor, steps) variant, the AEC env's and the core's cycles/s; for those of
    :data:`TRAIN_VARIANTS`, also ``meta`` training's frames/s (for ``train_seconds``; none when 0)."""
    result = {}
    for floor in FLOORS:
        for steps in STEPS:
            with scene_variant(floor, steps):
                aec, _ = env_speed.bench_aec(seconds, warmup, seed)
                core = env_speed.bench_core(CORE_ROOMS, seconds, warmup, seed)
                result[floor, steps] = {"aec": aec, "core_n64": core}
                if train_seconds and (floor, steps) in TRAIN_VARIANTS:
                    meta = train_speed.bench_method("meta", None, train_seconds, warmup_iters=2)
                    result[floor, steps]["meta"] = meta["frames_per_s"]
    return result


def main() -> None:
    """Parse the flags, time the variants and MiniWorld in alternation, and print the report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    env_speed.add_timing_flags(parser, seconds=3.0, warmup=0.5, per="figure")
    parser.add_argument(
        "--train-seconds",
        type=env_speed.at_least(float, "train-seconds", 0),
        default=20.0,
        help="timed seconds of meta training per round, as shipped and with the cheapest cycle (20; 0: none)",
    )
    args = parser.parse_args()

    import activeperc_env  # noqa: F401 (chooses the GL backend, e.g. MUJOCO_GL=egl)

    if args.train_seconds:  # train as activeperc-train and train_speed.py do
        import torch

        from activeperc_rl.allocator import keep_freed_memory
        from activeperc_rl.config import TrainConfig

        torch.set_num_threads(TrainConfig().torch_threads)
        keep_freed_memory()

    machine = env_speed.machine_info()
    print("activeperc scene cost vs MiniWorld")
    print(f"machine: {machine['usable_cpus']} usable CPUs ({machine['cpu_count']} total), {machine['processor']}")
    timing = f"{args.seconds:g} s per figure after {args.warmup:g} s warm-up, seed {args.seed}"
    print(f"timing:  {timing}; {args.rounds} round(s), MiniWorld timed before the first and after each")
    print()
    print("one 0.2-s move from rest in an empty room, by physics step: 'turn left' in degrees, 'forward' in metres")
    for timestep in MOTION_TIMESTEPS:
        with scene_variant(timestep=timestep):
            turn, forward = first_moves()
        steps = f"{timestep * 1000:4g} ms steps ({round(0.2 / timestep):2d} a cycle)"
        print(f"  {steps}: {turn:+6.1f} deg {forward:6.3f} m")
    print()

    def measure(i: int) -> dict[tuple[str, int], dict[str, float]]:
        figures = measure_round(args.seconds, args.warmup, args.seed, args.train_seconds)
        rates = "; ".join(
            f"{f} {n}: " + ", ".join(f"{k} {v:.0f}" for k, v in r.items()) for (f, n), r in figures.items()
        )
        print(f"round {i + 1}: {rates}", flush=True)
        return figures

    measured = peer.in_rounds(args.rounds, measure, args.seconds, args.warmup, args.seed)
    print()
    print(peer.describe(measured, width=24))
    if not measured.peer:
        return
    ratios = {
        (variant, figure): peer.bracketed_ratios([r[variant][figure] for r in measured.ours], measured.peer)
        for variant, figures in measured.ours[0].items()
        for figure in figures
    }
    print()
    print("median ratio to MiniWorld (each round's ratio in brackets); cycles/s are medians")
    for floor in FLOORS:
        print(f"floor {floor}:")
        for steps in STEPS:
            cells = []
            for figure, label in (("aec", "AEC env"), ("core_n64", "core N=64")):
                rate = statistics.median(r[floor, steps][figure] for r in measured.ours)
                cells.append(f"{label} {rate:6.0f} cycles/s {peer.spread(ratios[(floor, steps), figure], 2, 'x')}")
            print(f"  {steps:2d} of 40 steps: " + "   ".join(cells))
    if args.train_seconds:
        print("meta training (TrainConfig defaults, 16 rooms):")
        for floor, steps in TRAIN_VARIANTS:
            rate = statistics.median(r[floor, steps]["meta"] for r in measured.ours)
            spread = peer.spread(ratios[(floor, steps), "meta"], 2, "x")
            print(f"  {floor} floor, {steps:2d} of 40 steps: {rate:6.0f} frames/s {spread}")
    print()
    for (figure, multiple), goal in GOALS.items():
        if (TRAIN_VARIANTS[0], figure) not in ratios:
            continue
        met = [
            f"{steps} of 40 steps, {floor} floor"
            for floor in FLOORS
            for steps in STEPS
            if ((floor, steps), figure) in ratios and statistics.median(ratios[(floor, steps), figure]) >= multiple
        ]
        print(f"goal  {goal}: met with {'; '.join(met) if met else 'none of these'}")


if __name__ == "__main__":
    main()
