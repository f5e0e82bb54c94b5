"""Which pinning of torch's CPU kernels trains the same bits on CPUs of different vendors.

It trains the golden training trace's runs (``tests/golden.py``: ``meta`` and ``fixed_forward``, seed 0, 3,072
frames) under each candidate pinning, adds this CPU vendor's digests of their saved networks and optimizers to
``benchmarks/results/portable_bits.json`` and prints every candidate's digests by vendor. Run it on an Intel and
on an AMD machine, or under a CPU that QEMU emulates; a candidate whose digests agree across the vendors trains
the same bits on both.

With ``--census`` (and ``--emulate``) it also files, per run, how many distinct addresses of the code QEMU
translated (its ``-d in_asm`` log, disassembled block by block with capstone) hold each floating-point instruction
whose result the CPU model defines (:data:`CPU_DEFINED`: the approximate reciprocals and reciprocal square roots,
the x87 transcendentals), which QEMU computes its own way. ``unfused_adam`` is the control: MKL's square root takes
``rsqrtps`` there. It needs ``apt install qemu-user`` and capstone (the ``dev`` extra).

Run it from the repository root::

    python benchmarks/portable_bits.py                 # every candidate (about 10 minutes on 2 cores)
    python benchmarks/portable_bits.py --only portable
    python benchmarks/portable_bits.py --only portable --emulate Haswell-v4   # an Intel CPU (about 25 minutes)
    python benchmarks/portable_bits.py --only portable unfused_adam --emulate Haswell-v4 --census
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import re
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

import golden  # noqa: E402 (tests/ on the path first)

from activeperc_rl.runtime.atomic import atomic_path  # noqa: E402
from activeperc_rl.runtime.portable import PINNED_ENVIRONMENT, cpu_capability, cpu_vendor, has_avx2, machine  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results" / "portable_bits.json"
CANDIDATES = {  # name: (the pinning variables, the convolutions' library: golden.CONVOLUTIONS, --portable given)
    "mkl_avx2": (PINNED_ENVIRONMENT | {"MKL_CBWR": "AVX2,STRICT"}, "onednn", False),  # MKL on its AVX2 branch
    "unfused_adam": (PINNED_ENVIRONMENT, "onednn", False),  # --portable before it took the fused Adam step
    "unfused_adam_nnpack": (PINNED_ENVIRONMENT, "nnpack", False),  # oneDNN off: NNPACK convolves 16 or more images
    "portable": (PINNED_ENVIRONMENT, "onednn", True),  # activeperc-train --portable
    "portable_aten_conv": (PINNED_ENVIRONMENT, "aten", True),  # oneDNN and NNPACK off: ATen's im2col, MKL's products
}

CPU_DEFINED = frozenset(
    ("rcpps", "rcpss", "rsqrtps", "rsqrtss", "vrcpps", "vrcpss", "vrsqrtps", "vrsqrtss")
    + ("fsin", "fcos", "fsincos", "fptan", "fpatan", "f2xm1", "fyl2x", "fyl2xp1")
)
"""The x86 floating-point instructions of AVX2 CPUs (as capstone names them) whose results each CPU model defines."""
# a line of QEMU's in_asm log: an address and the bytes there (QEMU's own decoding after them is not used)
_LOGGED = re.compile(r"^0x([0-9a-f]+):  ((?:[0-9a-f]{2} )*[0-9a-f]{2})(?:  |\s*$)")


def train(candidate: str, method: str, out: Path, emulate: str | None = None, log: Path | None = None) -> str:
    """Train ``method`` as the golden trace does, pinned as ``candidate`` says, into ``out`` (under QEMU's ``emulate``
    CPU if given, which writes the code it translates to ``log`` if given): its weights' digest."""
    pins, convolutions, portable_flag = CANDIDATES[candidate]
    golden.train_portable(method, out, pins, convolutions, portable_flag, emulate, log)
    return golden.training_trace(out)["weights"]


def train_candidate(candidate: str, folder: Path, emulate: str | None, take_census: bool) -> tuple[dict, dict]:
    """Train each method of the golden trace pinned as ``candidate`` says, in ``folder``: the weights' digests by
    method, and (``take_census``, under ``emulate``) each run's :func:`census`."""
    digests, counts = {}, {}
    for method in golden.TRAINING_METHODS:
        log = folder / f"{candidate}_{method}.in_asm" if take_census else None
        digests[method] = train(candidate, method, folder / candidate / method, emulate, log)
        if log:
            counts[method] = census(log)
            log.unlink()
    return digests, counts


def translated_blocks(log: Path):
    """The blocks of code in QEMU's in_asm log, as (address, bytes): each runs on from its first instruction."""
    start, code = None, bytearray()
    with open(log, errors="replace") as file:
        for line in file:
            match = _LOGGED.match(line)
            address = int(match[1], 16) if match else None
            if start is not None and address != start + len(code):
                yield start, bytes(code)
                start, code = None, bytearray()
            if match:
                start = address if start is None else start
                code += bytes.fromhex(match[2])
    if start is not None:
        yield start, bytes(code)


def census(log: Path) -> dict[str, int]:
    """Of the code QEMU translated (its in_asm ``log``), disassembled block by block: how many distinct addresses
    hold each :data:`CPU_DEFINED` instruction, how many hold any (``translated``) and how many bytes did not
    disassemble (``undecoded``); ``ValueError`` where the log holds no code."""
    import capstone

    decoder = capstone.Cs(capstone.CS_ARCH_X86, capstone.CS_MODE_64)
    seen, logged, decoded = set(), 0, 0
    for start, code in translated_blocks(log):
        logged += len(code)
        for address, size, mnemonic, _ in decoder.disasm_lite(code, start):
            seen.add((address, mnemonic))
            decoded += size
    if not seen:
        raise ValueError(f"{log} holds no code QEMU translated (was it written by qemu-x86_64 -d in_asm?)")
    counts = {"translated": len({address for address, _ in seen}), "undecoded": logged - decoded}
    for _, mnemonic in seen:
        if mnemonic in CPU_DEFINED:
            counts[mnemonic] = counts.get(mnemonic, 0) + 1
    return counts


def table(stored: dict) -> str:
    """Every candidate's digests by vendor, and whether the vendors that used the candidate's pins of today agree."""
    vendors = sorted({vendor for by_vendor in stored.values() for vendor in by_vendor})
    methods = golden.TRAINING_METHODS
    lines = [f"| candidate | {' | '.join(vendors)} | vendors agree |", "|---" * (len(vendors) + 2) + "|"]
    for candidate, by_vendor in stored.items():
        cells = [", ".join(by_vendor[v].get(m, "?") for m in methods) if v in by_vendor else "" for v in vendors]
        today = [e for e in by_vendor.values() if e.get("pins") == CANDIDATES[candidate][0]]
        digests = [{m: entry.get(m) for m in methods} for entry in today]
        if len(digests) > 1:
            agree = "yes" if all(d == digests[0] for d in digests) else "no"
        else:
            agree = "made with other pins" if len(by_vendor) > 1 else "one vendor so far"
        lines.append(f"| {candidate} | {' | '.join(cells)} | {agree} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Parse the flags, train every candidate, record this vendor's digests and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", choices=CANDIDATES, default=list(CANDIDATES), help="candidates to train")
    parser.add_argument("--emulate", metavar="CPU", help="train under qemu-x86_64 -cpu CPU (e.g. Haswell-v4)")
    parser.add_argument("--census", action="store_true", help="count the CPU-defined instructions (with --emulate)")
    args = parser.parse_args(argv)
    if args.census and not args.emulate:
        parser.error("--census reads QEMU's log of the code it translates: give --emulate CPU too")
    if args.census and importlib.util.find_spec("capstone") is None:
        parser.error("--census disassembles with capstone: pip install capstone (it comes with the dev extra)")
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
            digests, counts = train_candidate(candidate, Path(folder), args.emulate, args.census)
            old = stored.setdefault(candidate, {}).get(vendor, {})
            if not counts and all(old.get(m) == digest for m, digest in digests.items()):
                counts = old.get("census", {})  # the same runs: their census holds
            entry = digests | {"pins": CANDIDATES[candidate][0]} | ({"census": counts} if counts else {})
            stored[candidate][vendor] = entry
            print(f"{candidate}: {digests}" + (f", census {counts}" if counts else ""), flush=True)
            with atomic_path(RESULTS) as temporary:  # each candidate's digests kept as soon as they are made
                temporary.write_text(json.dumps(stored, indent=1) + "\n")
    print(table(stored))


if __name__ == "__main__":
    main()
