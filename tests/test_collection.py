"""Collection through TorchRL's collectors (``collect_workers``): same layouts, current weights, clean stops."""

import multiprocessing
import os
import signal
import subprocess
import sys
import time

import pytest
import torch
from conftest import assert_same_run, default_stop_signals
from tensordict.nn import TensorDictSequential
from test_train import TINY, read_metrics, run_cli, wait_for_rows
from torch import nn

from activeperc_env import EnvConfig
from activeperc_rl import cli
from activeperc_rl.collection import Rollouts, WorkerError
from activeperc_rl.envs import make_env
from activeperc_rl.models import FixedLooker, make_actor, make_encoder
from activeperc_rl.runtime.checkpoint import load_checkpoint

SMALL = EnvConfig(max_cycles=6)


def mover_that_always_picks(action: int):
    """A mover actor whose output layer ignores the image and makes ``action`` all but certain."""
    actor = make_actor(make_encoder(SMALL, (4,), 8), 8, "mover")
    pick(actor, action)
    return actor


def pick(actor, action: int) -> None:
    out = actor[0].module.out
    with torch.no_grad():
        out.weight.zero_()
        out.bias.fill_(-50.0)
        out.bias[action] = 50.0


def survivors(session: int, wait_s: float = 20.0) -> list[str]:
    """Command lines of the processes left in ``session`` after up to ``wait_s`` seconds."""
    deadline = time.monotonic() + wait_s
    while True:
        ps = subprocess.run(["ps", "-e", "-o", "sid=,args="], capture_output=True, text=True).stdout.splitlines()
        left = [line for line in ps if line.split()[0] == str(session)]
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.5)


class FailingLooker(nn.Module):
    """Fails in an env of two rooms, holds the camera in any other."""

    def forward(self, tensordict):
        if tensordict.batch_size[0] == 2:
            raise ArithmeticError("this looker fails with two rooms")
        return FixedLooker()(tensordict)


@pytest.mark.parametrize("collector, rooms", [("process", 5), ("ray", 4)])  # Ray splits the rooms evenly only
def test_rooms_split_over_workers_keep_their_layouts_and_act_with_the_current_weights(collector, rooms):
    actor = mover_that_always_picks(2)
    policy = TensorDictSequential(actor, FixedLooker())
    rollouts = Rollouts(
        policy, None, SMALL, rooms, rollout_length=4, workers=2, collector=collector, env_seed=7, torch_seed=0
    )
    try:
        first = next(rollouts)
        pick(actor, 0)  # the workers must see this change before the next rollout
        second = next(rollouts)
    finally:
        rollouts.shutdown()
    assert first.batch_size == second.batch_size == torch.Size([rooms, 4])
    assert (first["mover", "action"] == 2).all() and (second["mover", "action"] == 0).all()
    # room i of the split env starts in the layout of room i of one env of all the rooms
    reference = make_env(rooms, seed=7, config=SMALL).reset()
    assert torch.equal(first["mover", "observation", "image"][:, 0], reference["mover", "observation", "image"])
    # trajectory ids stay unique across the workers' rooms
    ids = first["collector", "traj_ids"][:, 0]
    assert len(set(ids.tolist())) == rooms


def test_each_worker_samples_from_a_stream_of_its_own():
    """Workers with as many rooms each would draw the same actions from one seed: less exploration than k = 0."""
    from activeperc_rl.models import RandomPolicy

    collector = Rollouts(RandomPolicy(("mover", "looker")), None, SMALL, 4, 8, workers=2, env_seed=7, torch_seed=0)
    try:
        actions = next(collector)["mover", "action"]
    finally:
        collector.shutdown()
    assert not torch.equal(actions[:2], actions[2:])  # worker 0's two rooms against worker 1's


def test_a_failing_worker_is_reported_with_its_error_and_no_worker_is_left():
    # 3 rooms over 2 workers: worker 0 holds 2 rooms and fails, worker 1 holds 1 and starts fine
    with pytest.raises(
        WorkerError, match="collector: a worker failed to start: ArithmeticError: this looker fails with two rooms"
    ):
        Rollouts(
            mover_that_always_picks(2), FailingLooker(), SMALL, 3, 4, workers=2, env_seed=0,
            torch_seed=0,
        )  # fmt: skip
    assert multiprocessing.active_children() == []


def test_a_killed_worker_is_named_with_the_signal_that_killed_it():
    policy = TensorDictSequential(mover_that_always_picks(2), FixedLooker())
    collector = Rollouts(policy, None, SMALL, 2, 4, workers=2, env_seed=0, torch_seed=0)
    try:
        next(collector)
        collector.collector.procs[1].kill()
        collector.collector.procs[1].join()
        with pytest.raises(WorkerError, match=r"collector worker 1 died \(killed by SIGKILL\)"):
            next(collector)
    finally:
        collector.shutdown()
    assert multiprocessing.active_children() == []


def worker_pids(parent: int) -> list[int]:
    """Process ids of the collector workers that ``parent`` spawned."""
    ps = subprocess.run(["ps", "-ww", "-e", "-o", "pid=,ppid=,args="], capture_output=True, text=True).stdout
    return [int(line.split()[0]) for line in ps.splitlines() if int(line.split()[1]) == parent and "spawn_main" in line]


def shm_managers() -> set[int]:
    """Process ids of the torch_shm_manager processes running (each a session of its own, under init)."""
    ps = subprocess.run(["ps", "-ww", "-e", "-o", "pid=,args="], capture_output=True, text=True).stdout
    return {int(line.split()[0]) for line in ps.splitlines() if line.split()[1:] == ["torch_shm_manager"]}


# a worker, or the helper process through which the weights reach the workers (it hung the run for good)
@pytest.mark.parametrize("killed", ["worker", "torch_shm_manager"])
def test_a_worker_killed_mid_run_ends_the_run_with_one_line_and_a_resumable_checkpoint(tmp_path, killed):
    out = tmp_path / "run"
    command = [
        sys.executable, "-m", "activeperc_rl.cli", *TINY, "--out", str(out), "--frames", "10000000",
        "--collect-workers", "2", "--method", "fixed_forward",
    ]  # fmt: skip
    earlier = shm_managers()
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    try:
        wait_for_rows(out, 3)
        (worker, *_) = worker_pids(process.pid) if killed == "worker" else shm_managers() - earlier
        os.kill(worker, signal.SIGKILL)
        _, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:  # no run left behind when the test fails
            os.killpg(process.pid, signal.SIGKILL)
    assert process.returncode == 1, err
    assert "Traceback" not in err
    # without the manager, sending the weights fails, or a worker that reaches for it first aborts
    named = ["died (killed by SIGKILL)"] if killed == "worker" else ["(torch_shm_manager)", "died (killed by SIGABRT)"]
    assert any(name in err for name in named) and f"continue with --resume --out {out}" in err
    assert not survivors(process.pid), "a worker outlived the run"
    trained = load_checkpoint(out / "checkpoint.pt")["frames"]
    target = str(trained + 64)
    assert cli.main(["--out", str(out), "--resume", "--frames", target, "--no-progress", "--eval-episodes", "0"]) == 0
    assert int(read_metrics(out)[-1]["frames"]) >= trained + 64


def test_training_with_workers_repeats_itself_also_across_a_resume(tmp_path):
    """The same run twice, the second stopped at 100 frames and resumed with as many workers: the checkpoint
    holds each worker's rooms, carried step and torch random state (at a constant learning rate, which a resume to
    a larger budget leaves as it was)."""
    workers = ["--collect-workers", "2", "--lr-schedule", "constant"]
    runs = [
        run_cli(tmp_path, "--method", "meta", "--frames", frames, *workers, name=f"r{i}")
        for i, frames in enumerate(("300", "100"))
    ]
    assert cli.main(["--out", str(runs[1]), "--resume", "--frames", "300", "--no-progress"]) == 0
    rows = assert_same_run(*runs, columns=("frames", "success_rate", "mean_return", "episodes"))
    assert int(rows[-1]["frames"]) >= 300


def start_run(out, *args) -> subprocess.Popen:
    """``activeperc-train`` of the tiny config and ``args`` into ``out``, for ever, in a session of its own with the
    default stop signals (output and errors in one text pipe)."""
    command = [sys.executable, "-m", "activeperc_rl.cli", *TINY, "--out", str(out), "--frames", "10000000", *args]
    return subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
        preexec_fn=default_stop_signals,
    )


@pytest.mark.parametrize(
    ("stop", "rows"),
    [(signal.SIGINT, 12), (signal.SIGTERM, 3), (signal.SIGHUP, 3)],
    ids=["ctrl-c", "sigterm", "sighup"],
)
def test_a_stop_signal_to_the_process_group_stops_the_workers_and_saves(tmp_path, stop, rows):
    """SIGINT (a terminal's Ctrl-C), SIGTERM (a scheduler's stop) or SIGHUP (a closing terminal) to the whole
    process group; Ctrl-C after curriculum's switch of environments (which comes after 10 rows)."""
    out = tmp_path / "run"
    process = start_run(out, "--method", "curriculum", "--curriculum-fraction", "0.00003", "--collect-workers", "2")
    wait_for_rows(out, rows, timeout=240)
    os.killpg(process.pid, stop)
    output, _ = process.communicate(timeout=120)
    assert process.returncode == 0, output
    if stop != signal.SIGHUP:  # after a SIGHUP the run writes to /dev/null what it wrote to a pipe (a tee's, say)
        assert "checkpoint saved" in output
    assert "Traceback" not in output and "resource_tracker" not in output, output  # no helper process died
    assert load_checkpoint(out / "checkpoint.pt")["frames"] == int(read_metrics(out)[-1]["frames"]) >= rows * 32
    assert not survivors(process.pid), "a worker outlived the run"
    target = str(load_checkpoint(out / "checkpoint.pt")["frames"] + 64)
    assert cli.main(["--out", str(out), "--resume", "--frames", target, "--no-progress", "--eval-episodes", "0"]) == 0


def test_a_dead_worker_of_meta_names_its_environment():
    """meta runs E1 and E2, each with its own workers: the message says which one lost a worker."""
    from activeperc_rl.recipe import TrainConfig, make_method

    config = TrainConfig.from_options(
        num_envs=2, rollout_length=4, collect_workers=1, channels=(8,), hidden_size=16, env=SMALL
    )
    method = make_method(config, torch.device("cpu"))
    try:
        method.e2.collector.procs[0].kill()
        method.e2.collector.procs[0].join()
        with pytest.raises(WorkerError, match=r"E2's collector worker 0 died \(killed by SIGKILL\)"):
            method.iterate()
    finally:
        method.close()
    assert multiprocessing.active_children() == []


def test_a_worker_that_cannot_be_started_leaves_none_running(monkeypatch):
    """The second worker's process fails to start (out of processes, say): the first one is stopped too."""
    import multiprocessing.context

    start, starts = multiprocessing.context.SpawnProcess.start, []

    def start_once(process):
        starts.append(process.name)
        if len(starts) == 2:
            raise OSError("Resource temporarily unavailable")
        start(process)

    monkeypatch.setattr(multiprocessing.context.SpawnProcess, "start", start_once)
    policy = TensorDictSequential(mover_that_always_picks(2), FixedLooker())
    with pytest.raises(OSError, match="Resource temporarily unavailable"):
        Rollouts(policy, None, SMALL, 2, 4, workers=2, env_seed=0, torch_seed=0)
    assert len(starts) == 2
    assert multiprocessing.active_children() == []


def test_ray_needs_rooms_that_split_evenly():
    with pytest.raises(ValueError, match="num_envs=5 does not split evenly over 2 Ray workers"):
        Rollouts(mover_that_always_picks(2), None, SMALL, 5, 4, workers=2, collector="ray",
                 env_seed=0, torch_seed=0)  # fmt: skip


def test_ray_without_ray_installed_says_how_to_install_it(monkeypatch):
    import importlib.util

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "ray" else find_spec(name, *a))
    with pytest.raises(ValueError, match=r"collector='ray' needs Ray, which is not installed: pip install"):
        Rollouts(mover_that_always_picks(2), None, SMALL, 4, 4, workers=2, collector="ray",
                 env_seed=0, torch_seed=0)  # fmt: skip
