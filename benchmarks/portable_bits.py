"""Which pinning of torch's CPU kernels trains the same bits on CPUs of different vendors.

It trains the golden training trace's runs (``tests/golden.py``: ``meta`` and ``fixed_forward``, seed 0, 3,072
frames) under each candidate pinning, adds this CPU vendor's digests of their saved networks and optimizers to
``benchmarks/results/portable_bits.json`` and prints every candidate's digests by vendor. Run it on an Intel and
on an AMD machine; a candidate whose digests agree across the vendors trains the same bits on both.

Run it from the repository root::

    python benchmarks/portable_bits.py                 # every candidate (about 5 minutes on 2 cores)
    python benchmarks/portable_bits.py --only portable
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

import golden  # noqa: E402 (tests/ on the path first)

from activeperc_rl.atomic import atomic_path  # noqa: E402
from activeperc_rl.portable import PINNED_ENVIRONMENT, cpu_vendor, machine  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results" / "portable_bits.json"
CANDIDATES = {  # name: (environment of the training process, whether torch may call oneDNN)
    "mkl_avx2": (PINNED_ENVIRONMENT | {"MKL_CBWR": "AVX2,STRICT"}, True),  # MKL on its AVX2 branch
    "portable": (PINNED_ENVIRONMENT, True),  # activeperc-train --portable
    "portable_no_onednn": (PINNED_ENVIRONMENT, False),  # convolutions in ATen's kernels instead of oneDNN's
}
# activeperc-train in a process that sets torch's oneDNN switch first (no variable sets it)
TRAIN = "import sys, torch; torch.backends.mkldnn.enabled = {}; from activeperc_rl import cli; sys.exit(cli.main())"


def train(candidate: str, method: str, out: Path) -> str:
    """Train ``method`` as the golden trace does, pinned as ``candidate`` says, into ``out``: its weights' digest."""
    variables, onednn = CANDIDATES[candidate]
    environment = {k: v for k, v in os.environ.items() if k not in PINNED_ENVIRONMENT} | variables
    flags = [flag for flag in golden.TRAINING_FLAGS if flag != "--portable"]  # pinned here, not by a restart
    command = [sys.executable, "-c", TRAIN.format(onednn), "--method", method, *flags, "--out", str(out)]
    subprocess.run(command, env=environment, check=True, capture_output=True, text=True)
    (digest,) = golden.training_trace(out)["weights"].values()
    return digest


def table(stored: dict) -> str:
    """Every candidate's digests (``meta``, ``fixed_forward``) by vendor, and whether the vendors agree."""
    vendors = sorted({vendor for by_vendor in stored.values() for vendor in by_vendor})
    lines = [f"| candidate | {' | '.join(vendors)} | vendors agree |", "|---" * (len(vendors) + 2) + "|"]
    for candidate, by_vendor in stored.items():
        cells = [", ".join(by_vendor[v][m] for m in golden.TRAINING_METHODS) if v in by_vendor else "" for v in vendors]
        agree = "yes" if len({tuple(d.items()) for d in by_vendor.values()}) == 1 else "no"
        lines.append(f"| {candidate} | {' | '.join(cells)} | {agree if len(by_vendor) > 1 else 'one vendor so far'} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Parse the flags, train every candidate, record this vendor's digests and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", choices=CANDIDATES, default=list(CANDIDATES), help="candidates to train")
    args = parser.parse_args(argv)
    stored = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    vendor = cpu_vendor()
    print(f"# {machine()}, {vendor}")
    with tempfile.TemporaryDirectory() as folder:
        for candidate in args.only:
            digests = {
                method: train(candidate, method, Path(folder) / candidate / method)
                for method in golden.TRAINING_METHODS
            }
            stored.setdefault(candidate, {})[vendor] = digests
            print(f"{candidate}: {digests}", flush=True)
    with atomic_path(RESULTS) as temporary:
        temporary.write_text(json.dumps(stored, indent=1) + "\n")
    print(table(stored))


if __name__ == "__main__":
    main()
