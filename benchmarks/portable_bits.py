"""Which pinning of torch's CPU kernels trains the same bits on CPUs of different vendors.

It trains the golden training trace's runs (``tests/golden.py``: ``meta`` and ``fixed_forward``, seed 0, 3,072
frames) under each candidate pinning, adds this CPU vendor's digests of their saved networks and optimizers to
``benchmarks/results/portable_bits.json`` and prints every candidate's digests by vendor. Run it on an Intel and
on an AMD machine, or under a CPU that QEMU emulates; a candidate whose digests agree across the vendors trains
the same bits on both.

Run it from the repository root::

    python benchmarks/portable_bits.py                 # every candidate (about 10 minutes on 2 cores)
    python benchmarks/portable_bits.py --only portable
    python benchmarks/portable_bits.py --only portable --emulate Haswell-v4   # an Intel CPU (about 25 minutes)
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

import golden  # noqa: E402 (tests/ on the path first)

from activeperc_rl.atomic import atomic_path  # noqa: E402
from activeperc_rl.portable import PINNED_ENVIRONMENT, cpu_capability, cpu_vendor, has_avx2, machine  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results" / "portable_bits.json"
CANDIDATES = {  # name: (the pinning variables, the convolutions' library: golden.CONVOLUTIONS, --portable given)
    "mkl_avx2": (PINNED_ENVIRONMENT | {"MKL_CBWR": "AVX2,STRICT"}, "onednn", False),  # MKL on its AVX2 branch
    "unfused_adam": (PINNED_ENVIRONMENT, "onednn", False),  # --portable before it took the fused Adam step
    "unfused_adam_nnpack": (PINNED_ENVIRONMENT, "nnpack", False),  # oneDNN off: NNPACK convolves 16 or more images
    "portable": (PINNED_ENVIRONMENT, "onednn", True),  # activeperc-train --portable
    "portable_aten_conv": (PINNED_ENVIRONMENT, "aten", True),  # oneDNN and NNPACK off: ATen's im2col, MKL's products
}


def train(candidate: str, method: str, out: Path, emulate: str | None = None) -> str:
    """Train ``method`` as the golden trace does, pinned as ``candidate`` says, into ``out`` (under QEMU's ``emulate``
    CPU if given): its weights' digest."""
    pins, convolutions, portable_flag = CANDIDATES[candidate]
    golden.train_portable(method, out, pins, convolutions, portable_flag, emulate)
    (digest,) = golden.training_trace(out)["weights"].values()
    return digest


def table(stored: dict) -> str:
    """Every candidate's digests (``meta``, ``fixed_forward``) by vendor, and whether the vendors agree (digests
    made with other pins, or stored without them before 2026-12-05, are not compared)."""
    vendors = sorted({vendor for by_vendor in stored.values() for vendor in by_vendor})
    methods = golden.TRAINING_METHODS
    lines = [f"| candidate | {' | '.join(vendors)} | vendors agree |", "|---" * (len(vendors) + 2) + "|"]
    for candidate, by_vendor in stored.items():
        cells = [", ".join(by_vendor[v].get(m, "?") for m in methods) if v in by_vendor else "" for v in vendors]
        digests = [{m: entry.get(m) for m in methods} for entry in by_vendor.values()]
        pins = {json.dumps(entry.get("pins"), sort_keys=True) for entry in by_vendor.values()}
        agree = "one vendor so far" if len(digests) < 2 else "yes" if all(d == digests[0] for d in digests) else "no"
        agree = "made with other pins" if len(digests) > 1 and len(pins) > 1 else agree
        lines.append(f"| {candidate} | {' | '.join(cells)} | {agree} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Parse the flags, train every candidate, record this vendor's digests and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", choices=CANDIDATES, default=list(CANDIDATES), help="candidates to train")
    parser.add_argument("--emulate", metavar="CPU", help="train under qemu-x86_64 -cpu CPU (e.g. Haswell-v4)")
    args = parser.parse_args(argv)
    try:
        golden.emulated(args.emulate)  # QEMU is there, before any training starts
    except ValueError as error:
        parser.error(str(error))
    if not has_avx2():
        parser.error(f"every candidate pins torch's kernels to AVX2, and this CPU's are {cpu_capability()}")
    stored = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    vendor = f"emulated {args.emulate}" if args.emulate else cpu_vendor()
    print(f"# {vendor}" if args.emulate else f"# {machine()}, {vendor}")
    with tempfile.TemporaryDirectory() as folder:
        for candidate in args.only:
            digests = {
                m: train(candidate, m, Path(folder) / candidate / m, args.emulate) for m in golden.TRAINING_METHODS
            }
            stored.setdefault(candidate, {})[vendor] = digests | {"pins": CANDIDATES[candidate][0]}
            print(f"{candidate}: {digests}", flush=True)
            with atomic_path(RESULTS) as temporary:  # each candidate's digests kept as soon as they are made
                temporary.write_text(json.dumps(stored, indent=1) + "\n")
    print(table(stored))


if __name__ == "__main__":
    main()
