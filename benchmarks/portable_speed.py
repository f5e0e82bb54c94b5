"""What portable mode costs in training frames/s, in rounds of fresh trainings.

Torch's CPU kernels as torch picks them, with oneDNN capped at AVX2, and with ``--portable``; the digests of
their networks say which runs agree.

Run it from the repository root::

    python benchmarks/portable_speed.py                    # meta, 20,000 frames, 3 rounds (10 min for 3 modes, more)
    python benchmarks/portable_speed.py --method fixed_forward --frames 10000 --rounds 1
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import harness

from activeperc_env.rooms import ROOMS
from activeperc_rl.methods import METHODS
from activeperc_rl.runtime.portable import PINNED_ENVIRONMENT, machine, state_digest

MODES = {  # name: (extra environment, extra flags of activeperc-train)
    "default": ({}, ()),  # torch's own choice (AVX-512 on a CPU that has it)
    "onednn": ({"ONEDNN_MAX_CPU_ISA": "AVX2"}, ()),  # only the convolutions' library capped
    "portable": ({}, ("--portable",)),  # activeperc-train --portable
}


def train(mode: str, method: str, frames: int, out: Path, recipe: tuple[str, ...] = ()) -> tuple[float, str]:
    """Train in ``mode`` into ``out`` (``recipe``: more flags of activeperc-train, such as ``--preset pilot``):
    (frames/s after the first iteration, digest of the saved networks)."""
    import torch

    extra, flags = MODES[mode]
    environment = {k: v for k, v in os.environ.items() if k not in PINNED_ENVIRONMENT} | extra
    command = [sys.executable, "-m", "activeperc_rl.cli", "--method", method, "--frames", str(frames), *recipe, *flags]
    command += ["--eval-episodes", "0", "--no-progress", "--out", str(out)]
    subprocess.run(command, env=environment, check=True, capture_output=True, text=True)
    with open(out / "metrics.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    first, last = rows[0], rows[-1]
    rate = (int(last["frames"]) - int(first["frames"])) / (float(last["time_s"]) - float(first["time_s"]))
    state = torch.load(out / "checkpoint.pt", map_location="cpu", weights_only=False)
    return rate, state_digest(state["method"])


def main(argv: list[str] | None = None) -> None:
    """Parse the flags, train every mode in rounds and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--method", choices=METHODS, default="meta", help="method to train (meta)")
    parser.add_argument(
        "--frames", type=harness.at_least(int, "frames", 1), default=20_000, help="frames per run (20000)"
    )
    parser.add_argument("--rounds", type=harness.at_least(int, "rounds", 1), default=3, help="rounds of every mode (3)")
    parser.add_argument("--preset", choices=("paper", "pilot"), help="train activeperc-train's named preset")
    parser.add_argument("--version", type=int, choices=tuple(ROOMS), help="train in this room (default: the preset's)")
    args = parser.parse_args(argv)
    recipe = (
        *(("--preset", args.preset) if args.preset else ()),
        *(("--version", str(args.version)) if args.version is not None else ()),
    )
    import torch

    print(
        f"# {machine()} (torch's own kernels), {os.cpu_count()} CPUs, torch {torch.__version__}, "
        f"{time.strftime('%Y-%m-%d')}; {args.method}, {args.frames} frames{' ' + ' '.join(recipe) if recipe else ''}"
    )
    rates = {mode: [] for mode in MODES}
    digests = {mode: set() for mode in MODES}
    with tempfile.TemporaryDirectory() as folder:
        for round_ in range(args.rounds):
            for mode in MODES:
                rate, digest = train(mode, args.method, args.frames, Path(folder) / f"{mode}{round_}", recipe)
                rates[mode].append(rate)
                digests[mode].add(digest)
            print(f"round {round_ + 1}: " + ", ".join(f"{mode} {rates[mode][-1]:,.0f}" for mode in MODES) + " frames/s")
    print("| mode | frames/s (median) | x default (median of rounds) | networks' digest |")
    print("| --- | --- | --- | --- |")
    for mode in MODES:
        ratio = statistics.median(r / d for r, d in zip(rates[mode], rates["default"], strict=True))
        print(f"| {mode} | {statistics.median(rates[mode]):,.0f} | {ratio:.2f} | {', '.join(sorted(digests[mode]))} |")


if __name__ == "__main__":
    main()
