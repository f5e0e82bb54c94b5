"""Which of torch's CPU operations round alike on every CPU: a digest of each on fixed inputs, under portable pins.

The operations that training calls and that may round by CPU (MKL's vector maths, Adam's steps), the mover's
network trained three steps with each library of convolutions and each Adam step, and the views the renderer draws.

Run it on one machine, and again on another or under an emulated CPU (QEMU's user mode, ``apt install qemu-user``);
each run adds its digests to ``benchmarks/results/portable_ops.json`` under the machine's name, and an operation
whose digests differ rounds by CPU. Portable mode's pins are set for it (as ``--portable`` sets them)::

    python benchmarks/portable_ops.py                                   # this CPU
    python benchmarks/portable_ops.py --emulate Haswell-v4              # an Intel CPU, emulated (about 2 minutes)
    python benchmarks/portable_ops.py --emulate EPYC-Rome-v2
    python benchmarks/portable_ops.py --emulate Haswell-v4 --without GALLIUM_DRIVER  # one pin left out (llvmpipe)
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
from functools import partial
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

import golden  # noqa: E402 (tests/ on the path first)

from activeperc_rl.runtime.atomic import atomic_path  # noqa: E402
from activeperc_rl.runtime.portable import PINNED_ENVIRONMENT, cpu_vendor, machine  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "portable_ops.json"
VIEWS_ROOM = 1
"""The room whose views the ``views`` operation draws: the one the stored digests were taken in (then the default)."""


def digests() -> dict[str, str]:
    """16 hex digits of each operation's result on 100,000 fixed inputs (one thread), of three Adam steps, and of
    the mover's network trained three steps with each library of convolutions (:func:`_network`), of the views of
    seeded rooms (:func:`_views`); and how many of the 100,000 square roots are not correctly rounded
    (``sqrt_inexact``)."""
    import torch

    torch.set_num_threads(1)
    generator = torch.Generator().manual_seed(0)
    x = (torch.rand(100_000, generator=generator) - 0.5) * 20
    positive = x.abs() + 1e-3
    operations = {
        "sin": lambda: x.sin(),
        "cos": lambda: x.cos(),
        "exp": lambda: x.exp(),
        "log": lambda: positive.log(),
        "sqrt": lambda: positive.sqrt(),
        "pow_0.5": lambda: positive.pow(0.5),
        "tanh": lambda: x.tanh(),
        "logsumexp": lambda: x.view(-1, 4).logsumexp(-1),
        "log_softmax": lambda: x.view(-1, 4).log_softmax(-1),
        "reciprocal": lambda: positive.reciprocal(),
        "std": lambda: x.view(-1, 100).std(-1),
        "norm": lambda: x.view(-1, 100).norm(dim=-1),
        "adam": lambda: _adam(x, fused=None),
        "adam_fused": lambda: _adam(x, fused=True),
    }
    for convolutions in golden.CONVOLUTIONS:
        for fused in (None, True):
            operations[f"network_{convolutions}{'_fused' if fused else ''}"] = partial(_network, convolutions, fused)
    operations["views"] = _views
    taken = {name: hashlib.sha256(f().numpy().tobytes()).hexdigest()[:16] for name, f in operations.items()}
    # how many of the float32 roots are not the correctly rounded ones (float64's root, rounded once)
    taken["sqrt_inexact"] = str(int((positive.sqrt() != positive.double().sqrt().float()).sum()))
    return taken


def _adam(x, fused: bool | None):
    import torch

    parameter = x.clone().requires_grad_()
    parameter.grad = x.flip(0) * 1e-3
    optimizer = torch.optim.Adam([parameter], lr=3e-4, eps=1e-5, fused=fused)
    for _ in range(3):
        optimizer.step()
    return parameter.detach()


def _network(convolutions: str, fused: bool | None):
    """The default room's mover network after three Adam steps on batches of 1, 16 and 256 random views (two
    threads, the convolutions in the library ``convolutions`` names: ``golden.CONVOLUTIONS``): its outputs, gradients
    and weights."""
    import torch

    from activeperc_env import EnvConfig
    from activeperc_rl.models import Head, make_encoder

    torch.set_num_threads(2)
    torch.backends.mkldnn.enabled, nnpack = golden.CONVOLUTIONS[convolutions]
    torch.backends.nnpack.set_flags(nnpack)
    torch.manual_seed(0)
    env = EnvConfig(version=VIEWS_ROOM)  # the networks' shapes: every room with a range sensor has the same
    network = Head(make_encoder(env, (16, 32), 256), 256, 3)
    optimizer = torch.optim.Adam(network.parameters(), lr=3e-4, eps=1e-5, fused=fused)
    generator = torch.Generator().manual_seed(1)
    seen = []
    for batch in (1, 16, 256):
        image = torch.randint(0, 256, (batch, env.height, env.width, 3), generator=generator, dtype=torch.uint8)
        pan = torch.rand(batch, 1, generator=generator)
        ranges = torch.rand(batch, env.range_rays, generator=generator) * env.range_max
        logits = network(image, pan, ranges)
        loss = -torch.log_softmax(logits, -1)[:, 0].mean() + logits.pow(2).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        seen += [logits.detach().flatten(), *(p.grad.flatten() for p in network.parameters())]
    torch.set_num_threads(1)
    return torch.cat([*seen, *(p.detach().flatten() for p in network.parameters())])


def _views():
    """The views of golden.SEEDS' rooms of room :data:`VIEWS_ROOM` at both fields of view over five cycles of seeded
    random moves and looks (before and after each look; no episode ends in five cycles)."""
    import numpy as np
    import torch

    seen = []
    for fov in (60, 100):
        for _, _, s_bar, s in golden.seeded_cycles(VIEWS_ROOM, fov, cycles=5, rng_seed=0):
            seen += [s_bar, s]
    return torch.from_numpy(np.stack(seen))


def table(stored: dict) -> str:
    """Each operation's digests by machine, and whether the machines that took it agree."""
    machines = sorted(stored)
    lines = [f"| operation | {' | '.join(machines)} | agree |", "|---" * (len(machines) + 2) + "|"]
    for name in dict.fromkeys(name for machine_ in machines for name in stored[machine_]):
        cells = [stored[m].get(name, "") for m in machines]
        present = {cell for cell in cells if cell}
        agree = "one machine so far" if sum(map(bool, cells)) < 2 else "yes" if len(present) == 1 else "no"
        lines.append(f"| {name} | {' | '.join(cells)} | {agree} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Parse the flags, take the digests in a pinned process (emulated with ``--emulate``), add them to
    :data:`RESULTS` under this machine's name and print every machine's."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--emulate", metavar="CPU", help="run under qemu-x86_64 -cpu CPU (e.g. Haswell-v4)")
    parser.add_argument(
        "--without", metavar="VARIABLE", choices=PINNED_ENVIRONMENT, help="leave this one of the pins unset"
    )
    parser.add_argument("--digests", action="store_true", help=argparse.SUPPRESS)  # the pinned process's part
    args = parser.parse_args(argv)
    if args.digests:
        print(json.dumps({"machine": machine(), "digests": digests()}))
        return
    try:
        wrapper = golden.emulated(args.emulate)
    except ValueError as error:
        parser.error(str(error))
    # torch reads the pins when it starts: the digests come from a fresh process, emulated or not
    command = [*wrapper, sys.executable, __file__, "--digests"]
    pins = {name: value for name, value in PINNED_ENVIRONMENT.items() if name != args.without}
    environment = {name: value for name, value in os.environ.items() if name not in PINNED_ENVIRONMENT} | pins
    result = subprocess.run(command, env=environment, capture_output=True, text=True)
    if result.returncode:
        raise SystemExit(f"{' '.join(command)} failed:\n{result.stderr[-2000:]}")
    taken = json.loads(result.stdout)  # the pinned process names its kernels (AVX2)
    name = f"emulated {args.emulate}" if args.emulate else f"{cpu_vendor()} ({taken['machine']})"
    name += f", without {args.without}" if args.without else ""
    stored = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    stored[name] = taken["digests"]
    with atomic_path(RESULTS) as temporary:
        temporary.write_text(json.dumps(stored, indent=1) + "\n")
    print(table(stored))


if __name__ == "__main__":
    main()
