"""Collection on Ray (``--collector ray``) in a local Ray instance of two CPUs: the runs of the process collector."""

import os
import signal

import pytest
import ray
from conftest import assert_same_run
from test_collection import start_run
from test_train import read_metrics, run_cli, wait_for_rows

from activeperc_rl import cli
from activeperc_rl.methods import METHODS
from activeperc_rl.runtime.checkpoint import load_checkpoint

RAY = ["--collect-workers", "2", "--collector", "ray"]


@pytest.fixture(scope="module", autouse=True)
def local_ray():
    """One Ray instance for the module's tests (each collector joins it instead of starting one)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


@pytest.mark.parametrize("method", sorted(set(METHODS) - {"meta"}))
def test_every_method_trains_on_ray(tmp_path, method):
    out = run_cli(tmp_path, "--method", method, "--frames", "64", "--eval-episodes", "0", *RAY)
    assert int(read_metrics(out)[-1]["frames"]) >= 64


def test_meta_on_ray_is_the_run_of_the_process_collector_also_across_a_resume(tmp_path):
    """The same rooms reach the learner from Ray's workers as from processes, and a resumed Ray run repeats the
    uninterrupted one."""
    frames = ("--method", "meta", "--eval-episodes", "0", "--frames")
    on_processes = run_cli(tmp_path, *frames, "128", "--collect-workers", "2", name="processes")
    on_ray = run_cli(tmp_path, *frames, "128", *RAY, name="ray")
    resumed = run_cli(tmp_path, *frames, "64", *RAY, name="resumed")
    assert cli.main(["--out", str(resumed), "--resume", "--frames", "128", "--no-progress"]) == 0
    assert_same_run(on_processes, on_ray)
    assert_same_run(on_ray, resumed)


def test_ctrl_c_saves_a_checkpoint_of_a_ray_run_that_resumes(tmp_path):
    """Ctrl-C reaches the run's process group, Ray's own processes included: the run saves, then stops Ray."""
    out = tmp_path / "run"
    process = start_run(out, "--method", "meta", *RAY)
    try:
        wait_for_rows(out, 3, timeout=240)
        os.killpg(process.pid, signal.SIGINT)
        output, _ = process.communicate(timeout=120)
    finally:
        if process.poll() is None:  # no run left behind when the test fails
            os.killpg(process.pid, signal.SIGKILL)
    assert process.returncode == 0 and "checkpoint saved" in output and "Traceback" not in output, output
    saved = load_checkpoint(out / "checkpoint.pt")["frames"]
    assert saved == int(read_metrics(out)[-1]["frames"])
    assert cli.main(["--out", str(out), "--resume", "--frames", str(saved + 64), "--no-progress"]) == 0
