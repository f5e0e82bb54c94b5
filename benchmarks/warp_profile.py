"""Where a cycle of the warp backend goes, against the number of rooms: the bare ``Simulator(backend="warp")`` under
random actions split by its methods, and the device's own share of it.

For each N: cycles/s of :func:`harness.core_cycle` (move, render, look, render, resets) summed over the rooms, and
milliseconds per cycle in each ``Simulator`` method; then, each replayed alone and synchronised, a control period of
physics for all rooms on the device (``WarpBatch.advance``), a pass of the renderer over all views
(``WarpRenderer.draw``) and the copy of the views' bytes to the host; the device memory the N rooms took; and the
TorchRL env (``make_env(backend="warp")`` under random actions, as ``env_scaling.py`` steps it) split by the
simulator's methods that its step calls, the rest being the env's own (TorchRL, the looker, tensors).

Run it from the repository root (needs the ``warp`` extra)::

    python benchmarks/warp_profile.py --device cuda --num-envs 1024 4096 16384 --csv /tmp/warp_profile.csv
    python benchmarks/warp_profile.py --device cpu --num-envs 4 --seconds 1 --warmup 1   # Warp's CPU device
"""

from __future__ import annotations

import argparse
import gc
import time
from pathlib import Path

import harness

ENV_PARTS = ("move", "look", "reset", "observe")  # the Simulator methods a TorchRL env step calls
CSV_COLUMNS = (
    "num_envs",
    "cycles_per_s",
    *(f"{part}_ms" for part in harness.SIMULATOR_PARTS),
    "device_physics_ms",
    "device_render_ms",
    "views_to_host_ms",
    "device_mib_per_room",
    "env_cycles_per_s",
    *(f"env_{part}_ms" for part in (*ENV_PARTS, "rest")),
)


def device_ms(work, device: str, repeats: int) -> float:
    """Milliseconds per call of ``work`` on ``device``, over ``repeats`` calls after one untimed, synchronised."""
    import warp

    work()
    warp.synchronize_device(device)
    start = time.perf_counter()
    for _ in range(repeats):
        work()
    warp.synchronize_device(device)
    return 1e3 * (time.perf_counter() - start) / repeats


def free_mib(device: str) -> float | None:
    """The device's free memory in MiB (``None`` on the CPU)."""
    import warp

    found = warp.get_device(device)
    return found.free_memory / 2**20 if found.is_cuda else None


def profile(num_envs: int, device: str, seconds: float, warmup: float, seed: int, repeats: int) -> dict:
    """:func:`harness.core_cycle`'s rate and split with ``num_envs`` rooms on ``device``, and the device's parts."""
    before = free_mib(device)
    sim, rng = harness.random_core(num_envs, seed, backend="warp", device=device)
    try:
        rate, per_cycle = harness.timed_core(sim, rng, seconds, warmup)
        after = free_mib(device)
        batch, renderer = sim._batch, sim.renderer
        row = {
            "num_envs": num_envs,
            "cycles_per_s": rate * num_envs,
            **{f"{part}_ms": 1e3 * per_cycle[part] for part in harness.SIMULATOR_PARTS},
            "device_physics_ms": device_ms(lambda: batch.advance(sim.substeps), device, repeats),
            "device_render_ms": device_ms(renderer.draw, device, repeats),
            "views_to_host_ms": device_ms(lambda: renderer.views_on_host(num_envs), device, repeats),
            "device_mib_per_room": None if before is None else (before - after) / num_envs,
        }
    finally:
        sim.close()
    return row | env_profile(num_envs, device, seconds, warmup, seed)


def env_profile(num_envs: int, device: str, seconds: float, warmup: float, seed: int) -> dict:
    """Cycles/s of the TorchRL env with ``num_envs`` rooms on ``device``, summed over the rooms, and milliseconds per
    cycle in each of its simulator's methods of :data:`ENV_PARTS` and in the rest of its step."""
    rooms = harness.RandomRooms(num_envs, seed, backend="warp", device=device)
    stopwatch = harness.Stopwatch()

    def cycle() -> int:
        rooms.cycle()
        return 1

    try:
        with stopwatch.watching(rooms.env.sim, ENV_PARTS):
            rate, per_cycle = harness.timed_parts(cycle, seconds, warmup, stopwatch)
    finally:
        rooms.close()
    parts = {f"env_{part}_ms": 1e3 * per_cycle[part] for part in ENV_PARTS}
    rest = 1e3 / rate - sum(parts.values())
    return {"env_cycles_per_s": rate * num_envs, **parts, "env_rest_ms": rest}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command-line flags, every value checked."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--num-envs", nargs="+", type=harness.at_least(int, "num_envs", 1), default=[1024, 4096], metavar="N"
    )
    parser.add_argument("--device", default="cuda", help="Warp's device: cuda, cuda:N or cpu (default: cuda)")
    parser.add_argument("--seconds", type=harness.at_least(float, "seconds", 0, strict=True), default=5.0)
    parser.add_argument("--warmup", type=harness.at_least(float, "warmup", 0), default=2.0)
    parser.add_argument("--repeats", type=harness.at_least(int, "repeats", 1), default=20, help="of each device part")
    parser.add_argument("--seed", type=harness.at_least(int, "seed", 0), default=0)
    parser.add_argument("--csv", type=Path, help="write the rows to this CSV (default: none)")
    args = parser.parse_args(argv)
    from activeperc_env.warp_backend import check_backend

    try:
        check_backend("warp", args.device)
    except ValueError as error:
        parser.error(str(error))
    harness.refuse_unwritable(parser, {"--csv": args.csv})
    return args


def main(argv: list[str] | None = None) -> list[dict]:
    """Profile every N and print a row each; return the rows."""
    args = parse_args(argv)
    print(f"activeperc warp backend profile on {args.device}: {args.seconds:g} s per N after {args.warmup:g} s warm-up")
    print(harness.machine_line(harness.machine_info()))
    print(" | ".join(CSV_COLUMNS))
    rows = []
    for n in dict.fromkeys(args.num_envs):
        rows.append(profile(n, args.device, args.seconds, args.warmup, args.seed, args.repeats))
        print(" | ".join("" if v is None else f"{v:.4g}" for v in rows[-1].values()), flush=True)
        gc.collect()
    if args.csv:
        harness.write_csv(args.csv, CSV_COLUMNS, [tuple(row.values()) for row in rows])
        print(f"wrote {args.csv}")
    return rows


if __name__ == "__main__":
    main()
