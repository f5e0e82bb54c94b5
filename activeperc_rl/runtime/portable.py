"""Portable mode: torch's CPU kernels and the renderer pinned, so that a run repeats on other x86-64 CPUs.

torch picks its CPU kernels (ATen's, oneDNN's, MKL's) by the CPU it finds, and kernels of another width round
differently; Mesa's llvmpipe compiles the views' shaders for the CPU it finds too, so portable mode draws with Mesa's
softpipe, which compiles nothing. Environment variables make those choices, each read once, when its library starts.
So the commands restart themselves with them set (:func:`restart_pinned`), and :func:`train` refuses a portable
config in a process that started without them (:func:`require_pinned`).
"""

from __future__ import annotations

import hashlib
import os
import platform
import sys
from contextlib import suppress

import torch

PINNED_ENVIRONMENT = {
    "ATEN_CPU_CAPABILITY": "avx2",
    "ONEDNN_MAX_CPU_ISA": "AVX2",
    "MKL_CBWR": "COMPATIBLE",
    "GALLIUM_DRIVER": "softpipe",
    "DRAW_USE_LLVM": "0",
}
"""The variables that pin torch's CPU kernels (ATen's and oneDNN's convolutions at AVX2, MKL's matrix products on
the branch that every vendor's CPU runs alike) and Mesa's software renderer (softpipe, its vertices without LLVM:
nothing compiled for the CPU), and their values."""
PINNED_CAPABILITY = "AVX2"
"""What ``torch.backends.cpu.get_cpu_capability()`` says in a pinned process."""
_AVX2_OR_WIDER = ("AVX2", "AVX512")


def cpu_capability() -> str:
    """The instruction set of the CPU kernels torch uses in this process (``AVX512``, ``AVX2``, ``DEFAULT``, ...)."""
    return torch.backends.cpu.get_cpu_capability()


def has_avx2() -> bool:
    """Whether torch found AVX2 (or wider) kernels on this CPU, the ones portable mode pins to."""
    return cpu_capability() in _AVX2_OR_WIDER


def machine() -> str:
    """This machine's CPU model and the kernels torch uses on it, e.g. ``"Intel(R) Xeon(R) Processor, AVX512"``."""
    model = platform.processor() or platform.machine()
    with suppress(OSError):
        with open("/proc/cpuinfo") as file:
            model = next((line.split(":", 1)[1].strip() for line in file if line.startswith("model name")), model)
    return f"{model}, {cpu_capability()}"


def cpu_vendor() -> str:
    """This CPU's vendor as Linux names it (``"GenuineIntel"``, ``"AuthenticAMD"``), or ``"unknown"``."""
    with suppress(OSError):
        with open("/proc/cpuinfo") as file:
            return next((line.split(":", 1)[1].strip() for line in file if line.startswith("vendor_id")), "unknown")
    return "unknown"


def _variables_set() -> bool:
    return all(os.environ.get(name) == value for name, value in PINNED_ENVIRONMENT.items())


def is_pinned() -> bool:
    """Whether this process's torch kernels are pinned (the variables set before torch started)."""
    return _variables_set() and cpu_capability() == PINNED_CAPABILITY


def _pinned_command() -> str:
    return " ".join(f"{name}={value}" for name, value in PINNED_ENVIRONMENT.items())


def require_pinned() -> None:
    """Raise ``ValueError`` unless this process is pinned: portable mode must start before torch does."""
    if not is_pinned():
        raise ValueError(
            f"portable=True needs torch's CPU kernels pinned before torch starts (this process uses "
            f"{cpu_capability()}): run activeperc-train --portable from a shell, which sets that up, or start "
            f"Python with {_pinned_command()}"
        )


def restart_pinned(prog: str) -> None:
    """Unless this process is pinned, replace it by the same command (``python -m activeperc_rl.<module>`` with its
    arguments) with the pinned variables set; ``ValueError`` where this CPU has no AVX2 kernels to pin to."""
    if is_pinned():
        return
    if _variables_set():
        raise ValueError(f"{_pinned_command()} are set and torch still uses {cpu_capability()} kernels")
    if not has_avx2():
        raise ValueError(
            f"portable mode pins torch's CPU kernels to AVX2, and this CPU's are {cpu_capability()}: "
            f"run without --portable (such runs repeat on the same kind of CPU)"
        )
    module = {"activeperc-train": "activeperc_rl.cli", "activeperc-eval": "activeperc_rl.evaluate"}[prog]
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, [sys.executable, "-m", module, *sys.argv[1:]], os.environ | PINNED_ENVIRONMENT)


def state_digest(state) -> str:
    """16 hex digits of the SHA-256 of every tensor and number in a nested state dict (a checkpoint's networks
    and optimizers), in key order: two runs that trained the same bits have the same digest."""
    h = hashlib.sha256()

    def walk(value) -> None:
        if isinstance(value, dict):
            for key in sorted(value, key=str):
                h.update(str(key).encode())
                walk(value[key])
        elif isinstance(value, (list, tuple)):
            for item in value:
                walk(item)
        elif isinstance(value, torch.Tensor):
            h.update(value.detach().cpu().contiguous().numpy().tobytes())
        else:
            h.update(repr(value).encode())

    walk(state)
    return h.hexdigest()[:16]
