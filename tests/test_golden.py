"""Every room version gives the episodes it always gave: golden traces through the core, PettingZoo and TorchRL;
and training in portable mode gives the run it always gave.

The committed digests (``tests/golden/traces.json``, written by ``python tests/golden.py``) cover the views, the
physics state, the range readings, rewards and ends of seeded rooms under fixed actions. v0's were written by the
code before v1 existed, so they prove the Figure 1 pilot's room unchanged. A failure names the first cycle that
differs: a MuJoCo, Mesa or numpy upgrade, or a change of ours, made the same seed give another episode.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from golden import (
    TRACES,
    TRAINING,
    TRAINING_RUNS,
    core_trace,
    parallel_env_trace,
    torchrl_trace,
    train_portable,
    training_trace,
)

from activeperc_env.rooms import ROOMS
from activeperc_rl.runtime import portable

STORED = json.loads(TRACES.read_text())


def first_difference(ours: list[str], stored: list[str]) -> str:
    for cycle, (mine, theirs) in enumerate(zip(ours, stored, strict=False)):
        if mine != theirs:
            return f"cycle {cycle}"
    return f"lengths {len(ours)} and {len(stored)}"


@pytest.mark.parametrize("version", ROOMS)
def test_core_gives_the_stored_episodes(version):
    ours, stored = core_trace(version), STORED[f"v{version}"]["core"]
    for fov, rows in stored.items():
        assert ours[fov] == rows, f"v{version} {fov}: first difference at {first_difference(ours[fov], rows)}"


# numpy picks its SIMD kernels (AVX-512, AVX2, SSE) and OpenBLAS its own by CPU, and some round differently
OTHER_KERNELS = {"NPY_DISABLE_CPU_FEATURES": "AVX512_SPR AVX512_ICL X86_V4 X86_V3", "OPENBLAS_CORETYPE": "Prescott"}


def test_the_core_gives_the_stored_episodes_with_other_numpy_and_blas_kernels():
    """The episodes do not depend on which SIMD kernels numpy and OpenBLAS picked on this CPU (a layout's heading
    from numpy's AVX-512 arctan2 once differed in its last bit from the same layout's elsewhere)."""
    code = "import json, golden; print(json.dumps({v: golden.core_trace(v) for v in golden.ROOMS}))"
    tests = str(Path(__file__).resolve().parent)
    environment = (
        os.environ
        | OTHER_KERNELS
        | {"PYTHONPATH": os.pathsep.join(filter(None, [tests, os.environ.get("PYTHONPATH")]))}
    )
    result = subprocess.run([sys.executable, "-c", code], env=environment, capture_output=True, text=True, check=True)
    for version, ours in json.loads(result.stdout).items():
        assert ours == STORED[f"v{version}"]["core"], f"v{version} differs with {OTHER_KERNELS}"


@pytest.mark.parametrize("version", ROOMS)
def test_pettingzoo_gives_the_stored_episodes(version):
    ours, stored = parallel_env_trace(version), STORED[f"v{version}"]["parallel_env"]
    assert ours == stored, f"v{version}: first difference at {first_difference(ours, stored)}"


@pytest.mark.parametrize("version", ROOMS)
def test_torchrl_env_gives_the_stored_episodes(version):
    ours, stored = torchrl_trace(version), STORED[f"v{version}"]["torchrl"]
    assert ours == stored, f"v{version}: first difference at {first_difference(ours, stored)}"


TRAINED = json.loads(TRAINING.read_text())
needs_avx2 = pytest.mark.skipif(not portable.has_avx2(), reason="portable mode pins torch's kernels to AVX2")


@pytest.fixture(scope="module")
def portable_runs(tmp_path_factory) -> dict[str, Path]:
    """The run directory of ``activeperc-train --portable`` of each golden training run."""
    folder = tmp_path_factory.mktemp("portable")
    for run in TRAINING_RUNS:
        train_portable(run, folder / run)
    return {run: folder / run for run in TRAINING_RUNS}


@needs_avx2
@pytest.mark.parametrize("run", TRAINING_RUNS)
def test_portable_training_gives_the_stored_metrics(portable_runs, run):
    """The first iterations of seed 0 in portable mode log the committed run's metrics, on Intel and AMD CPUs."""
    ours, stored = training_trace(portable_runs[run]), TRAINED[run]
    assert ours["metrics"] == stored["metrics"], (
        f"first difference at {first_difference(ours['metrics'], stored['metrics'])}"
    )


def test_the_stored_weights_were_trained_with_todays_pins():
    """Digests of weights trained under other pinning variables would compare other kernels' bits."""
    assert TRAINED.get("pinned") == portable.PINNED_ENVIRONMENT, "pins changed: python tests/golden.py training"


@needs_avx2
@pytest.mark.parametrize("run", TRAINING_RUNS)
def test_portable_training_gives_the_stored_weights(portable_runs, run):
    """Bit for bit the committed networks and optimizers, on every CPU with AVX2 (made on an AMD EPYC; an emulated
    Intel Haswell trains the same bits, executing no instruction whose result the silicon defines)."""
    ours, stored = training_trace(portable_runs[run])["weights"], TRAINED[run]["weights"]
    assert ours == stored, f"{portable.machine()} ({portable.cpu_vendor()}) trained {ours}, the stored run {stored}"


@needs_avx2
def test_a_portable_run_is_evaluated_with_pinned_kernels(portable_runs):
    """activeperc-eval on a portable run restarts itself pinned, and its JSON says which kernels it used."""
    command = [sys.executable, "-m", "activeperc_rl.evaluate", str(portable_runs["meta"]), "--episodes", "2", "--json"]
    result = json.loads(subprocess.run(command, capture_output=True, text=True, check=True).stdout)
    assert result["torch_cpu_capability"] == "AVX2" and result["episodes"] == 2
