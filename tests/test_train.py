"""The training pipeline end to end: every method from the CLI, checkpoints, resume, evaluation."""

import csv
import dataclasses
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
import torch
import yaml
from conftest import PseudoTerminal, assert_same_run, default_stop_signals

from activeperc_rl import cli, evaluate
from activeperc_rl import train as train_module
from activeperc_rl.envs import make_env
from activeperc_rl.losses import BEST_LOOK_SHARES
from activeperc_rl.methods import METHODS, Meta
from activeperc_rl.models import FixedLooker
from activeperc_rl.recipe import OPTION_SECTIONS, TrainConfig
from activeperc_rl.runtime.checkpoint import METRIC_COLUMNS, MetricsLog, load_checkpoint, save_checkpoint
from activeperc_rl.runtime.rundir import claim_run_dir, new_run_dir
from activeperc_rl.runtime.signals import stop_signals

# A few thousand frames on tiny settings: short episodes so that some end inside the run.
TINY = [
    "--num-envs", "4", "--rollout-length", "8", "--max-cycles", "12", "--channels", "8",
    "--hidden-size", "32", "--eval-episodes", "4", "--no-progress",
]  # fmt: skip


def run_cli(tmp_path, *args, name="run"):
    out = tmp_path / name
    assert cli.main([*TINY, "--out", str(out), *args]) == 0
    return out


def read_metrics(out):
    with open(out / "metrics.csv", newline="") as f:
        return list(csv.DictReader(f))


def rows_logged(out) -> int:
    """How many metrics rows the run in ``out`` has logged so far (0 before its ``metrics.csv`` exists)."""
    return len(read_metrics(out)) if (out / "metrics.csv").exists() else 0


def wait_for_rows(out, count: int, timeout: float = 120) -> None:
    """Wait until the run in ``out`` (another process) has logged ``count`` metrics rows, or ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while rows_logged(out) < count and time.monotonic() < deadline:
        time.sleep(0.2)


@pytest.mark.parametrize("method", METHODS)
def test_every_method_trains_from_the_cli(tmp_path, method):
    out = run_cli(tmp_path, "--method", method, "--frames", "2000", "--seed", "1")
    rows = read_metrics(out)
    frames = [int(r["frames"]) for r in rows]
    assert frames == sorted(frames) and frames[-1] >= 2000
    assert {"frames", "fps", "success_rate", "mean_return"} <= set(rows[0])
    saved = yaml.safe_load((out / "config.yaml").read_text())
    assert saved["method"] == method and saved["env"]["max_cycles"] == 12
    state = load_checkpoint(out / "checkpoint.pt")
    assert state["frames"] == frames[-1]
    result = json.loads((out / "eval.json").read_text())
    assert result["learned"]["episodes"] == result["random"]["episodes"] == 4
    assert any(p.name.startswith("events") for p in (out / "tb").iterdir())


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device: run it on a GPU machine")
@pytest.mark.parametrize("method", METHODS)
def test_every_method_trains_on_cuda_and_continues_on_the_cpu(tmp_path, method, capsys):
    out = run_cli(tmp_path, "--method", method, "--frames", "1000", "--device", "cuda", "--seed", "1")
    assert json.loads((out / "eval.json").read_text())["learned"]["episodes"] == 4
    assert cli.main(["--out", str(out), "--resume", "--frames", "1500", "--device", "cpu", "--no-progress"]) == 0
    assert int(read_metrics(out)[-1]["frames"]) >= 1500
    capsys.readouterr()
    assert evaluate.main([str(out), "--episodes", "3", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["episodes"] == 3


def test_same_seed_same_run(tmp_path):
    runs = [run_cli(tmp_path, "--method", "meta", "--frames", "600", name=f"r{i}") for i in range(2)]
    assert_same_run(*runs, columns=("frames", "success_rate", "mean_return", "episodes"))


def test_existing_run_is_not_overwritten(tmp_path, capsys):
    out = run_cli(tmp_path, "--frames", "200", "--method", "fixed_forward", "--eval-episodes", "0")
    assert f"activeperc-train: done, 224 frames; the run is in {out}" in capsys.readouterr().out
    assert cli.main([*TINY, "--out", str(out), "--frames", "400"]) == 2
    printed = capsys.readouterr()
    assert "already holds a run (checkpoint.pt, config.yaml, metrics.csv)" in printed.err and "--resume" in printed.err
    assert printed.out == ""  # no "training ... ->" line for a run that does not start


def test_resume_continues_to_the_new_budget(tmp_path):
    out = run_cli(tmp_path, "--method", "ia2c", "--frames", "256", "--eval-episodes", "0")
    before = read_metrics(out)
    assert cli.main(["--out", str(out), "--resume", "--frames", "768", "--no-progress"]) == 0
    frames = [int(r["frames"]) for r in read_metrics(out)]
    assert frames[: len(before)] == [int(r["frames"]) for r in before]
    assert frames == sorted(set(frames)) and frames[-1] >= 768


@pytest.mark.parametrize("method", METHODS)
def test_a_resumed_run_is_the_uninterrupted_run(tmp_path, method):
    """Stopped at 200 frames and resumed to 800, a run logs the same rows and ends with the same networks as one
    run straight to 800: the checkpoint holds the rooms and the collectors' carried step, not only the networks.
    (The curriculum switches at 196 frames in both, its switch point being a fraction of the first run's budget: the
    stop at 200 falls in the iteration that crosses it, and the resumed run must switch at its next one.) At a
    constant learning rate: a linear one spans the budget, which the resume changes (the next test's stop does not)."""
    tiny = ["--method", method, "--num-envs", "2", "--rollout-length", "4", "--eval-episodes", "0"]
    tiny += ["--lr-schedule", "constant"]
    fractions = ([], [])
    if method == "curriculum":
        fractions = (["--curriculum-fraction", "0.245"], ["--curriculum-fraction", "0.98"])
    whole = run_cli(tmp_path, *tiny, "--frames", "800", *fractions[0], name="whole")
    cut = run_cli(tmp_path, *tiny, "--frames", "200", *fractions[1], name="cut")
    assert cli.main(["--out", str(cut), "--resume", "--frames", "800", "--no-progress"]) == 0
    rows = assert_same_run(whole, cut)
    assert sum(int(r["episodes"]) for r in rows) > 0  # episodes ended: the rows are not all empty


def test_a_linear_schedule_spans_the_budget_through_a_stop_and_a_resume(tmp_path):
    """With ``lr_schedule: linear`` every learning rate falls with the frames trained out of ``run.frames``; a run
    stopped at a frame count (``train(stop_at=...)``) and resumed is the run straight to the end, schedule included."""
    tiny = ["--num-envs", "2", "--rollout-length", "4", "--eval-episodes", "0", "--frames", "800"]
    whole = run_cli(tmp_path, *tiny, "--lr-schedule", "linear", name="whole")
    config = cli.config_from_args(cli.build_parser().parse_args([*TINY, *tiny, "--lr-schedule", "linear"]))
    result = train_module.train(config, tmp_path / "cut", progress=False, stop_at=200)  # 9 iterations of 24 frames
    assert result["frames"] == 216 and not (tmp_path / "cut" / "eval.json").exists()
    assert cli.main(["--out", str(tmp_path / "cut"), "--resume", "--no-progress"]) == 0
    assert_same_run(whole, tmp_path / "cut")
    optimizers = load_checkpoint(whole / "checkpoint.pt")["method"]["optimizers"]
    scale = 1 - 792 / 800  # the last iteration starts after 792 frames
    assert optimizers["mover"]["param_groups"][0]["lr"] == pytest.approx(7e-4 * scale)
    assert optimizers["looker"]["param_groups"][0]["lr"] == pytest.approx(3e-4 * scale)
    with pytest.raises(ValueError, match="stop_at=0 is invalid"):
        train_module.train(config, tmp_path / "other", stop_at=0)


def test_a_resumed_run_with_a_frame_stack_is_the_uninterrupted_run(tmp_path):
    """The rooms' past views are part of what a checkpoint holds: a run stopped and resumed stacks the same views
    (and, with best_look, credits the same stacked views of every look)."""
    tiny = ["--num-envs", "2", "--rollout-length", "4", "--eval-episodes", "0", "--frame-stack", "3"]
    tiny += ["--bearing-bins", "0", "--version", "3", "--looker-credit", "best_look", "--lr-schedule", "constant"]
    whole = run_cli(tmp_path, *tiny, "--frames", "800", name="whole")
    cut = run_cli(tmp_path, *tiny, "--frames", "200", name="cut")
    assert cli.main(["--out", str(cut), "--resume", "--frames", "800", "--no-progress"]) == 0
    assert_same_run(whole, cut)
    video = tmp_path / "episode.mp4"  # its frames show the latest view
    assert evaluate.main([str(whole), "--episodes", "1", "--video", str(video)]) == 0
    assert iio.imread(video).shape[1:] == (240, 640, 3)


@pytest.mark.parametrize(
    "damage",
    [
        lambda c: c[0]["rooms"].update(episode_seeds=c[0]["rooms"]["episode_seeds"][:1]),
        lambda c: c.append(c[0]),
        lambda c: c[0]["rooms"]["sim"].update(physics=c[0]["rooms"]["sim"]["physics"][:, :-1]),
    ],
    ids=["seeds of one room", "a collector too many", "shorter state rows"],
)
def test_a_collection_state_that_does_not_fit_resumes_the_old_way_with_a_warning(tmp_path, capsys, damage):
    """Rooms' state from another MuJoCo (other state rows) or a damaged checkpoint: the networks still resume, the
    rooms start new episodes, and one line says that this resume is not exact."""
    out = run_cli(tmp_path, "--method", "fixed_forward", "--frames", "64", "--eval-episodes", "0")
    state = torch.load(out / "checkpoint.pt", weights_only=False)
    damage(state["collection"])
    save_checkpoint(out / "checkpoint.pt", state)
    capsys.readouterr()
    assert cli.main(["--out", str(out), "--resume", "--frames", "128", "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "warning: the rooms' state in" in err and "this resume is not the uninterrupted run" in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert int(read_metrics(out)[-1]["frames"]) >= 128


def test_a_fresh_run_leaves_an_earlier_runs_files_alone(tmp_path, capsys):
    out = tmp_path / "run"
    out.mkdir()
    (out / "metrics.csv").write_text("frames\n100\n")
    (out / "config.yaml").write_text("method: meta\n")
    assert cli.main([*TINY, "--out", str(out), "--frames", "64"]) == 2
    err = capsys.readouterr().err
    assert "config.yaml, metrics.csv" in err and "no checkpoint.pt" in err
    assert (out / "metrics.csv").read_text() == "frames\n100\n"


def test_a_second_process_in_the_same_run_directory_is_refused(tmp_path, capsys):
    out = tmp_path / "run"
    with claim_run_dir(out):  # as another activeperc-train would hold it
        assert cli.main([*TINY, "--out", str(out), "--frames", "64"]) == 2
    assert f"in use by another training process (pid {os.getpid()})" in capsys.readouterr().err
    assert not out.exists()  # the holder made it and wrote nothing, so it went with its lock
    run_cli(tmp_path, "--method", "fixed_forward", "--frames", "64", "--eval-episodes", "0")  # free again


def test_a_lock_file_removed_with_its_unused_directory_is_not_held(tmp_path, monkeypatch):
    """B opens the lock file of a directory that A made, then A ends without writing anything and removes the
    directory: B's lock on the removed file holds nothing, so B claims the directory anew and a third is refused."""
    import fcntl

    out = tmp_path / "run"
    first = claim_run_dir(out)
    first.__enter__()
    flock = fcntl.flock

    def after_the_first_left(fd, operation):
        if not left:
            first.__exit__(None, None, None)  # removes the lock file and the directory
            left.append(True)
        return flock(fd, operation)

    left = []

    monkeypatch.setattr(fcntl, "flock", after_the_first_left)
    with claim_run_dir(out):
        monkeypatch.undo()
        assert (out / ".lock").read_text() == f"{os.getpid()}\n"
        with pytest.raises(ValueError, match="in use by another training process"), claim_run_dir(out):
            pass


def test_resume_removes_what_a_killed_checkpoint_write_left_and_drops_a_torn_row(tmp_path):
    out = run_cli(tmp_path, "--method", "fixed_forward", "--frames", "64", "--eval-episodes", "0")
    (out / ".checkpoint.pt.k1ll3d.pt").write_bytes(b"half a checkpoint")
    with open(out / "metrics.csv", "a") as f:
        f.write("96,999,1.0,1.0,0.0,0.0,0\n")  # logged after the last checkpoint (64 frames)
        f.write("1")  # the start of the row being written (frames 128) when the process was killed
    assert cli.main(["--out", str(out), "--resume", "--frames", "128", "--no-progress"]) == 0
    assert not (out / ".checkpoint.pt.k1ll3d.pt").exists()
    rows = read_metrics(out)
    frames = [int(r["frames"]) for r in rows]
    assert frames == sorted(set(frames)) and frames[-1] >= 128
    assert "999" not in [r["iteration"] for r in rows]  # the checkpoint's run goes on from 64 frames


def test_meta_logs_its_meta_evaluator_and_looker_in_metrics_csv(tmp_path):
    """metrics.csv says whether a meta run's looker learned: M's mean and spread, the baseline, phi2's entropy,
    the pan rates of E1 and E2 and E2's success, one value per iteration."""
    out = run_cli(tmp_path, "--frames", "200", "--eval-episodes", "0", "--looker-credit", "trajectory")
    rows = read_metrics(out)
    logged = list(Meta.LOGGED.values())
    assert list(rows[0]) == [*METRIC_COLUMNS, *logged]
    for row in rows:
        values = {column: float(row[column]) for column in logged}  # e2_success_rate is nan without an episode
        assert values["meta_value_std"] >= 0 and 0 <= values["e1_pan_rate"] <= 1 and 0 <= values["e2_pan_rate"] <= 1
        assert 0 < values["looker_entropy"] <= math.log(3) + 1e-6
        assert all(math.isnan(values[share]) for share in BEST_LOOK_SHARES)  # the paper's credit values no views
    assert float(rows[0]["e2_pan_rate"]) > 0  # epsilon 0.3 pans at random in E2


def test_meta_with_the_best_look_credit_logs_how_often_phi2_picks_the_best_look(tmp_path):
    out = run_cli(tmp_path, "--frames", "200", "--eval-episodes", "0", "--looker-credit", "best_look")
    for row in read_metrics(out):
        shares = {share: float(row[share]) for share in BEST_LOOK_SHARES}
        assert all(0 <= share <= 1 for share in shares.values()), shares
        assert shares["best_look_left"] + shares["best_look_right"] <= 1


@pytest.mark.parametrize("method", ["ia2c", "joint"])
def test_baselines_with_a_looker_log_its_pan_rate_and_entropy_in_metrics_csv(tmp_path, method):
    """The looks of ia2c's looker and of the joint agent: the fraction that turned the camera and the entropy of the
    look (for the joint agent, of its marginal over the looks), one value per iteration."""
    out = run_cli(tmp_path, "--method", method, "--frames", "200", "--eval-episodes", "0", "--looker-hold-prob", "0.5")
    rows = read_metrics(out)
    assert list(rows[0]) == [*METRIC_COLUMNS, "pan_rate", "looker_entropy"]
    for row in rows:
        assert 0 < float(row["pan_rate"]) < 1  # half of the untrained looks hold
        assert math.log(3) - 0.2 < float(row["looker_entropy"]) <= math.log(3) + 1e-6  # (1/2, 1/4, 1/4): 1.04


def test_a_resumed_run_keeps_the_rows_of_an_older_metrics_log(tmp_path):
    """A run logged before the method's columns existed resumes: its rows stay, blank in the new columns."""
    out = run_cli(tmp_path, "--frames", "100", "--eval-episodes", "0")
    rows = read_metrics(out)
    with open(out / "metrics.csv", "w", newline="") as f:  # as the older code wrote it
        writer = csv.DictWriter(f, METRIC_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    assert cli.main(["--out", str(out), "--resume", "--frames", "200", "--no-progress"]) == 0
    resumed = read_metrics(out)
    assert [r["frames"] for r in resumed[: len(rows)]] == [r["frames"] for r in rows]
    assert resumed[0]["meta_value"] == "" and resumed[-1]["meta_value"] != ""


def test_a_metrics_log_with_a_bad_row_is_named(tmp_path):
    path = tmp_path / "metrics.csv"
    path.write_text(
        "frames,iteration,time_s,fps,success_rate,mean_return,episodes\n32,1,1,1,0,0,0\nx,2\n64,2,2,1,0,0,0\n"
    )
    with pytest.raises(ValueError, match=r"metrics.csv', line 3: not a metrics row"):
        MetricsLog(path, keep_until=64)
    path.write_text("step,loss\n1,2\n")
    with pytest.raises(ValueError, match="is not a metrics log"):
        MetricsLog(path, keep_until=64)


# before anything is written; while the first checkpoint is written; after it, while config.yaml is written
@pytest.mark.parametrize("stopped_in", ["make_method", "save_checkpoint", "save_yaml"])
def test_ctrl_c_while_the_run_starts_writes_nothing(tmp_path, monkeypatch, capsys, stopped_in):
    out = tmp_path / "run"

    def interrupted_start(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(train_module, stopped_in, interrupted_start)
    assert cli.main([*TINY, "--out", str(out), "--frames", "64"]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert not out.exists()  # made for the run and left unused: removed again
    monkeypatch.undo()
    run_cli(tmp_path, "--method", "fixed_forward", "--frames", "64", "--eval-episodes", "0")  # the same command again


def test_a_run_with_a_damaged_config_file_resumes_from_its_checkpoints_config(tmp_path, capsys):
    out = run_cli(tmp_path, "--method", "fixed_forward", "--frames", "64", "--eval-episodes", "0")
    written = (out / "config.yaml").read_text()
    (out / "config.yaml").write_text("run: {frames: [\n")  # garbled
    assert cli.main(["--resume", "--out", str(out), "--frames", "128", "--no-progress"]) == 0
    assert "config.yaml" in capsys.readouterr().err and int(read_metrics(out)[-1]["frames"]) >= 128
    assert (out / "config.yaml").read_text() == written.replace("frames: 64", "frames: 128")  # written again


def test_a_run_killed_before_its_config_was_written_resumes_from_its_checkpoint(tmp_path):
    out = run_cli(tmp_path, "--method", "fixed_forward", "--frames", "64", "--eval-episodes", "0")
    (out / "config.yaml").unlink()  # killed between the first checkpoint and config.yaml
    assert cli.main(["--resume", "--out", str(out), "--frames", "128", "--no-progress"]) == 0
    assert int(read_metrics(out)[-1]["frames"]) >= 128
    assert yaml.safe_load((out / "config.yaml").read_text())["run"]["frames"] == 128


def test_training_that_fails_midway_is_one_line_with_status_1(tmp_path, monkeypatch, capsys):
    """A ValueError raised by the learning itself (NaN logits after a divergence) is not a bad option: status 1,
    one line saying where it failed and which checkpoint is kept."""
    make_method = train_module.make_method

    def diverging(*args, **kwargs):
        method = make_method(*args, **kwargs)
        iterate, calls = method.iterate, []

        def iterate_then_fail():
            calls.append(1)
            if len(calls) == 3:
                raise ValueError("Expected parameter logits to satisfy the constraint Real(), but found invalid values")
            return iterate()

        method.iterate = iterate_then_fail
        return method

    monkeypatch.setattr(train_module, "make_method", diverging)
    out = tmp_path / "run"
    assert cli.main([*TINY, "--out", str(out), "--method", "fixed_forward", "--frames", "640"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("activeperc-train: error: training failed at iteration 3 (64 frames): Expected parameter")
    assert f"the checkpoint at 0 frames is kept in {out}" in err and "Traceback" not in err
    assert load_checkpoint(out / "checkpoint.pt")["frames"] == 0


def test_an_unwritable_run_directory_is_one_line(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    assert cli.main([*TINY, "--out", str(tmp_path / "file" / "run"), "--frames", "64"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("activeperc-train: error:") and "file" in err and "Traceback" not in err
    assert cli.main([*TINY, "--out", str(tmp_path / "file"), "--frames", "64"]) == 2
    assert f"--out {str(tmp_path / 'file')!r} is a file, not a directory" in capsys.readouterr().err


def test_a_run_that_fails_to_start_leaves_no_directory(tmp_path, capsys, monkeypatch):
    """A run refused after its directory was made (here: an image too small for the encoder) removes it again,
    the default runs/METHOD-seedS-TIME too (and runs/ if the run made it); a directory that existed before is left
    alone."""
    monkeypatch.chdir(tmp_path)
    small = ["--width", "8", "--height", "8", "--channels", "8", "8", "8", "--frames", "64"]
    assert cli.main([*TINY, *small]) == 2
    assert "activeperc-train: error:" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()  # it made runs/ too
    (tmp_path / "runs").mkdir()
    assert cli.main([*TINY, *small]) == 2
    assert list((tmp_path / "runs").iterdir()) == []  # a runs/ that was there stays
    assert cli.main([*TINY, *small, "--out", "new/run"]) == 2
    assert not (tmp_path / "new" / "run").exists()
    (tmp_path / "mine").mkdir()
    assert cli.main([*TINY, *small, "--out", "mine"]) == 2
    assert (tmp_path / "mine").is_dir()


def test_default_run_directories_of_the_same_second_differ(tmp_path):
    stem = tmp_path / "runs" / "meta-seed0-20261124-031500"
    assert [new_run_dir(stem).name for _ in range(3)] == [stem.name, f"{stem.name}-2", f"{stem.name}-3"]


def test_resume_with_other_options_names_them(tmp_path, capsys):
    out = run_cli(tmp_path, "--method", "joint", "--frames", "128", "--eval-episodes", "0")
    assert cli.main(["--out", str(out), "--resume", "--fov", "100", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "fov" in err and "60" in err and "100" in err
    saved = (out / "config.yaml").read_text()
    assert cli.main(["--out", str(out), "--resume", "--lr", "1e-3", "--num-envs", "2", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "lr: 0.0007 -> 0.001" in err and "num_envs: 4 -> 2" in err
    assert (out / "config.yaml").read_text() == saved
    assert cli.main(["--out", str(out), "--resume", "--frames", "160", "--checkpoint-every", "5", "--no-progress"]) == 0


def test_resume_below_the_trained_frames_is_refused(tmp_path, capsys):
    """--frames is a total: resuming to fewer frames than trained would only rewrite the run's config and eval."""
    out = run_cli(tmp_path, "--method", "fixed_forward", "--frames", "256", "--eval-episodes", "0")
    saved = (out / "config.yaml").read_text()
    assert cli.main(["--out", str(out), "--resume", "--frames", "100", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "frames=100" in err and "256" in err
    assert (out / "config.yaml").read_text() == saved and not (out / "eval.json").exists()


def test_resume_to_the_runs_own_target_after_it_overshot(tmp_path):
    """A run stops up to one iteration past --frames; re-running its command with --resume (e.g. after a
    Ctrl-C in its final evaluation) must not be refused as 'fewer frames than trained'."""
    out = run_cli(tmp_path, "--method", "fixed_forward", "--frames", "200", "--eval-episodes", "0")
    trained = load_checkpoint(out / "checkpoint.pt")["frames"]
    assert trained > 200  # 4 rooms x 8 steps per iteration: 7 iterations make 224
    assert cli.main([*TINY, "--out", str(out), "--resume", "--method", "fixed_forward", "--frames", "200"]) == 0
    assert load_checkpoint(out / "checkpoint.pt")["frames"] == trained
    assert json.loads((out / "eval.json").read_text())["learned"]["episodes"] == 4


def test_a_resume_that_trains_further_keeps_the_old_eval_under_its_frames(tmp_path, capsys):
    """eval.json describes the checkpoint beside it: one of an earlier checkpoint is kept as eval_FRAMES.json."""
    out = run_cli(tmp_path, "--method", "fixed_forward", "--frames", "64")
    old = (out / "eval.json").read_text()
    trained = json.loads(old)["frames"]
    capsys.readouterr()
    assert cli.main(["--out", str(out), "--resume", "--frames", "128", "--eval-episodes", "0", "--no-progress"]) == 0
    assert not (out / "eval.json").exists() and (out / f"eval_{trained}.json").read_text() == old
    assert f"eval.json is of the run at {trained} frames; kept as eval_{trained}.json" in capsys.readouterr().err


def test_a_resume_refused_for_a_damaged_metrics_log_changes_nothing_in_the_run(tmp_path, capsys):
    out = run_cli(tmp_path, "--method", "fixed_forward", "--frames", "64")
    lines = (out / "metrics.csv").read_text().splitlines(keepends=True)
    (out / "metrics.csv").write_text(lines[0] + "x,2\n" + "".join(lines[1:]))  # a garbled row before the last
    before = {path.name: path.read_bytes() for path in out.iterdir() if path.is_file()}
    capsys.readouterr()
    assert cli.main(["--out", str(out), "--resume", "--frames", "128", "--no-progress"]) == 2
    assert "metrics.csv', line 2: not a metrics row" in capsys.readouterr().err
    assert {path.name: path.read_bytes() for path in out.iterdir() if path.is_file()} == before


@pytest.mark.skipif(torch.cuda.is_available(), reason="needs a machine without CUDA")
def test_cuda_without_a_gpu_is_refused_before_the_run_directory_is_made(tmp_path, capsys):
    assert cli.main([*TINY, "--out", str(tmp_path / "run"), "--device", "cuda"]) == 2
    assert "cuda" in capsys.readouterr().err and not (tmp_path / "run").exists()


def test_resume_without_a_run_names_the_directory(tmp_path, capsys):
    assert cli.main(["--out", str(tmp_path / "nothing"), "--resume"]) == 2
    assert "nothing" in capsys.readouterr().err


def test_bad_flags_are_named(tmp_path, capsys):
    for main, argv in ((cli.main, ["--method", "dqn"]), (evaluate.main, [str(tmp_path), "--episodes", "dqn"])):
        with pytest.raises(SystemExit) as stop:
            main(argv)
        err = capsys.readouterr().err
        assert stop.value.code == 2 and "'dqn'" in err and err.count("\n") == 1, err  # one line, no usage block
    for main, argv in ((cli.main, ["--frames", "1.5"]), (evaluate.main, [str(tmp_path), "--seed", "1.5"])):
        with pytest.raises(SystemExit):
            main(argv)
        flag = argv[-2]
        assert f"argument {flag}: '1.5' is not a whole number" in capsys.readouterr().err  # not a function's name
    assert cli.main([*TINY, "--out", str(tmp_path / "x"), "--epsilon", "1.5"]) == 2
    assert "epsilon" in capsys.readouterr().err
    assert cli.main(["--resume"]) == 2
    assert "--resume needs --out RUN_DIR" in capsys.readouterr().err
    assert cli.main(["--resume", "--out", str(tmp_path / "x"), "--config", str(tmp_path / "p.yaml")]) == 2
    assert "--resume takes the run's own config.yaml; drop --config" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("looker_hold_prob", 1.0), ("looker_hold_prob", 0), ("mover_rollouts", "d2"), ("lr", 0), ("lr", "7e-4"),
        ("channels", 16), ("channels", ()), ("frames", True), ("shared_seeds", "no"), ("checkpoint_every", None),
        ("lr", float("inf")), ("max_grad_norm", float("nan")), ("entropy_coeff", float("inf")), ("seed", 2**63),
        ("rollout_length", 1), ("collect_workers", 33), ("frame_stack", 0), ("frame_stack", 17), ("looker_steps", 0),
        ("e2_rooms", -1), ("e2_rooms", 2**16 + 1), ("looker_encoder", "mover_bearing"),
        # sizes that failed deep in torch, mujoco or deque
        ("num_envs", 10**18), ("rollout_length", 10**18), ("hidden_size", 10**18), ("channels", (16, 10**18)),
        ("success_window", 10**19), ("torch_threads", 10**18), ("learner_threads", 10**18),
    ],
)  # fmt: skip
def test_invalid_training_value_names_the_field(field, value):
    section = OPTION_SECTIONS.get(field, "meta")
    with pytest.raises(ValueError, match=re.escape(f"{section}.{field}={value!r}")):
        TrainConfig.from_options(**{field: value})


def test_a_frame_stack_with_the_bearing_layout_is_refused():
    with pytest.raises(
        ValueError,
        match=re.escape("network.frame_stack=2 is invalid: expected an int in 1 .. 16, 1 with bearing_bins"),
    ):
        TrainConfig.from_options(frame_stack=2, bearing_bins=12)
    assert TrainConfig.from_options(frame_stack=2, bearing_bins=0).network.frame_stack == 2


def test_a_looker_that_remembers_on_an_encoder_of_one_view_is_refused():
    with pytest.raises(
        ValueError, match=re.escape("meta.looker_frames=4 is invalid: expected an int in 1 .. 16, 1 unless")
    ):
        TrainConfig.from_options(looker_frames=4, looker_encoder="mover")
    assert TrainConfig.from_options(looker_frames=4).stacked_views == 4


def test_mirrored_looks_without_a_credit_that_values_every_look_are_refused():
    with pytest.raises(ValueError, match=re.escape("meta.mirror_looks=True is invalid: expected true or false; true")):
        TrainConfig.from_options(mirror_looks=True, looker_credit="look")
    assert TrainConfig.from_options(mirror_looks=True, looker_credit="every_look").options.mirror_looks is True


def test_preset_then_flags(tmp_path):
    preset = tmp_path / "p.yaml"
    values = {"method": "joint", "joint": {"looker_hold_prob": 0.9}, "env": {"fov": 100, "max_cycles": 30}}
    preset.write_text(yaml.safe_dump(values))
    args = cli.build_parser().parse_args(["--config", str(preset), "--fov", "80", "--seed", "3"])
    config = cli.config_from_args(args)
    assert (config.method, config.options.looker_hold_prob, config.run.seed) == ("joint", 0.9, 3)
    assert (config.env.fov, config.env.max_cycles) == (80, 30)
    preset.write_text(yaml.safe_dump({"methd": "joint"}))
    with pytest.raises(ValueError, match="methd"):
        cli.config_from_args(cli.build_parser().parse_args(["--config", str(preset)]))


def test_a_flag_the_method_does_not_read_is_an_error_naming_it(tmp_path, capsys):
    for flags, named in [
        (["--method", "fixed_forward", "--looker-lr", "1"], "--looker-lr is not an option of method 'fixed_forward' "
         "(only of meta and ia2c)"),
        (["--method", "ia2c", "--epsilon", "0.1"], "--epsilon is not an option of method 'ia2c' (only of meta)"),
        (["--curriculum-fraction", "0.5"], "--curriculum-fraction is not an option of method 'meta' (only of "
         "curriculum)"),
        (["--method", "fixed_forward", "--looker-hold-prob", "0.5"], "(only of meta, joint, ia2c and curriculum)"),
    ]:  # fmt: skip
        assert cli.main([*flags, "--out", str(tmp_path / "run")]) == 2
        err = capsys.readouterr().err
        assert named in err and err.count("\n") == 1, err
        assert not (tmp_path / "run").exists()
    with pytest.raises(ValueError, match="method 'ia2c' does not read epsilon"):
        TrainConfig.from_options(method="ia2c", epsilon=0.1)


def test_a_preset_may_hold_other_methods_options_and_a_run_keeps_its_own(tmp_path):
    """A preset is a recipe for every method (the named presets are); a run's config.yaml holds its method's."""
    preset = tmp_path / "p.yaml"
    preset.write_text(yaml.safe_dump({"meta": {"epsilon": 0.1}, "ia2c": {"looker_lr": 1e-4}, "run": {"seed": 2}}))
    for method, options in (("meta", {"epsilon": 0.1}), ("ia2c", {"looker_lr": 1e-4}), ("joint", {})):
        args = cli.build_parser().parse_args(["--config", str(preset), "--method", method])
        config = cli.config_from_args(args)
        assert config.method == method and config.run.seed == 2
        assert all(getattr(config.options, name) == value for name, value in options.items())
        assert set(config.to_dict()) == {"method", "run", "a2c", "network", method, "env"}


def test_method_options_are_each_methods_own_fields():
    """The option tables come from the methods' option classes; no option name is both a method's and shared."""
    from activeperc_rl.methods import METHOD_CLASSES
    from activeperc_rl.recipe import METHOD_OPTIONS

    for name, readers in METHOD_OPTIONS.items():
        assert name not in OPTION_SECTIONS
        for method, cls in METHOD_CLASSES.items():
            assert (name in {f.name for f in dataclasses.fields(cls.Options)}) == (method in readers), (name, method)
    assert METHOD_OPTIONS["epsilon"] == ("meta",) and METHOD_OPTIONS["curriculum_fraction"] == ("curriculum",)
    assert METHOD_CLASSES["fixed_forward"].Options() == METHOD_CLASSES["fixed_forward"].Options.from_dict(None)


def test_preset_numbers_in_exponent_notation(tmp_path):
    """PyYAML reads 3e-5 as a string (YAML 1.1); presets read it as the number everyone means."""
    preset = tmp_path / "p.yaml"
    preset.write_text(
        "a2c:\n  lr: 7e-4\nmeta:\n  looker_lr: 3E-5\n  alpha: .5e-1\nrun:\n  frames: 2e6\nenv:\n  fov: 1e2\n"
    )
    config = cli.config_from_args(cli.build_parser().parse_args(["--config", str(preset)]))
    options = config.options
    assert (config.a2c.lr, options.looker_lr, options.alpha, config.run.frames, config.env.fov) == (
        7e-4, 3e-5, 0.05, 2e6, 100.0
    )  # fmt: skip
    assert type(config.run.frames) is int
    config = cli.config_from_args(cli.build_parser().parse_args(["--frames", "3e5", "--channels", "8", "1.6e1"]))
    assert (config.run.frames, config.network.channels) == (300_000, (8, 16))


@pytest.mark.parametrize(
    ("text", "named"),
    [
        ("run: {frames: 2.5e-1}\n", "run.frames=0.25"),
        ("env: {fov: '100'}\n", "EnvConfig.fov='100'"),
        ("network: {channels: 16}\n", "network.channels=16"),
        ("frames: 300\n", "put 'frames' under 'run:'"),
        ("epsilon: 0.1\n", "put 'epsilon' under its method's section ('meta:')"),
        ("run: {epsilon: 0.1}\n", "unknown run option(s) ['epsilon']"),
        ("meta: 3\n", "'meta' must be a mapping of options"),
        ("env: [1, 2]\n", "'env'"),
        ("env: []\n", "'env'"),
        ("env: false\n", "'env'"),
        ("method: meta\n  frames: [\n", "is not valid YAML at line 2, column 9: mapping values are not allowed here\n"),
        ("", "holds no options"),
        ("fov: 100\n", "put 'fov' under 'env:'"),
        ("# frames: 300\n", "holds no options"),
        ("run:\n  frames: 10\n  seed: 1\n  frames: 20\n", "at line 4, column 3: option 'frames' is given twice\n"),
        ("env:\n  fov: 60\n  fov: 90\n", "at line 3, column 3: option 'fov' is given twice\n"),
        (b"frames: \xff\n", "is not UTF-8 text (byte 8)\n"),
    ],
)
def test_bad_preset_values_are_named(tmp_path, capsys, text, named):
    preset = tmp_path / "p.yaml"
    preset.write_bytes(text if isinstance(text, bytes) else text.encode())
    assert cli.main(["--config", str(preset), "--out", str(tmp_path / "run"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert named in err and err.count("\n") == 1, err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    ("preset", "named"),
    [
        (None, "is a directory: give a YAML file"),
        ("", "config file '' is not a file name"),
        ("/dev/null", "config file '/dev/null' is not a regular file"),
        ("missing.yaml", "missing.yaml' does not exist"),
    ],
)
def test_a_preset_that_is_no_yaml_file_is_named(tmp_path, capsys, preset, named):
    preset = str(tmp_path) if preset is None else preset if preset in ("", "/dev/null") else str(tmp_path / preset)
    assert cli.main(["--config", preset, "--out", str(tmp_path / "run"), "--no-progress"]) == 2
    assert named in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_checkpoint_write_is_atomic(tmp_path, monkeypatch):
    path = tmp_path / "checkpoint.pt"
    save_checkpoint(path, {"frames": 1})

    write_bytes = Path.write_bytes

    def broken_write(self, data):  # a stop in the middle of writing the file
        write_bytes(self, bytes(data)[: len(data) // 2])
        raise KeyboardInterrupt

    monkeypatch.setattr(Path, "write_bytes", broken_write)
    with pytest.raises(KeyboardInterrupt):
        save_checkpoint(path, {"frames": 2})
    monkeypatch.undo()
    assert torch.load(path)["frames"] == 1
    assert [p.name for p in tmp_path.iterdir()] == ["checkpoint.pt"]  # no half-written file left beside it


def test_ctrl_c_saves_and_resume_finishes(tmp_path):
    out = tmp_path / "run"
    command = [sys.executable, "-m", "activeperc_rl.cli", *TINY, "--out", str(out), "--frames", "10000000"]
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, preexec_fn=default_stop_signals
    )
    wait_for_rows(out, 3)
    process.send_signal(signal.SIGINT)
    output, _ = process.communicate(timeout=120)
    assert process.returncode == 0, output
    assert "checkpoint saved" in output
    state = load_checkpoint(out / "checkpoint.pt")
    rows = read_metrics(out)
    assert state["frames"] == int(rows[-1]["frames"]) < 10_000_000
    target = state["frames"] + 256
    assert cli.main(["--out", str(out), "--resume", "--frames", str(target), "--no-progress"]) == 0
    frames = [int(r["frames"]) for r in read_metrics(out)]
    assert frames == sorted(set(frames)) and frames[-1] >= target
    assert (out / "eval.json").exists()
    assert not [p for p in os.listdir(out) if p.endswith(".tmp")]


def test_sighup_and_sigint_stop_a_run_unless_the_process_ignores_them():
    previous = {number: signal.getsignal(number) for number in (signal.SIGINT, signal.SIGHUP)}
    try:
        signal.signal(signal.SIGHUP, signal.SIG_IGN)  # as nohup starts a process
        signal.signal(signal.SIGINT, signal.default_int_handler)
        assert stop_signals() == [signal.SIGINT, signal.SIGTERM]
        signal.signal(signal.SIGHUP, signal.SIG_DFL)
        assert stop_signals() == [signal.SIGINT, signal.SIGTERM, signal.SIGHUP]
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a shell without job control starts 'cmd &'
        assert stop_signals() == [signal.SIGTERM, signal.SIGHUP]
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def test_a_hangup_saves_a_checkpoint_though_the_terminal_is_gone(tmp_path):
    """SIGHUP, as a closing terminal or a dropped SSH session sends: the run has its progress bar on that
    terminal, which is gone (writes to it fail), and still finishes its iteration, saves and exits."""
    out = tmp_path / "run"
    args = [arg for arg in TINY if arg != "--no-progress"]
    terminal = PseudoTerminal()
    command = [sys.executable, "-m", "activeperc_rl.cli", *args, "--out", str(out), "--frames", "10000000"]
    process = terminal.start(command)
    terminal.read_until(lambda: rows_logged(out) >= 3)
    terminal.hang_up()
    process.send_signal(signal.SIGHUP)
    assert process.wait(timeout=120) == 0
    assert b"frame/s" in terminal.seen  # the progress bar was on the terminal
    state = load_checkpoint(out / "checkpoint.pt")
    assert state["frames"] == int(read_metrics(out)[-1]["frames"]) < 10_000_000


def test_a_hangup_saves_a_checkpoint_though_the_tee_it_wrote_to_is_gone(tmp_path):
    """``activeperc-train 2>&1 | tee train.log`` in a terminal that closes: SIGHUP stops the tee and the run; the run
    must not die of writing into the tee's closed pipe before it saves."""
    out = tmp_path / "run"
    command = [sys.executable, "-m", "activeperc_rl.cli", *TINY, "--out", str(out), "--frames", "10000000"]
    tee, into_tee = os.pipe()
    process = subprocess.Popen(
        command, stdout=into_tee, stderr=into_tee, start_new_session=True, preexec_fn=default_stop_signals
    )
    os.close(into_tee)
    wait_for_rows(out, 3)
    os.close(tee)  # the tee is gone: writing into the pipe fails from now on
    process.send_signal(signal.SIGHUP)
    assert process.wait(timeout=120) == 0
    state = load_checkpoint(out / "checkpoint.pt")
    assert state["frames"] == int(read_metrics(out)[-1]["frames"]) < 10_000_000


def ignore_hangups_and_ctrl_c() -> None:
    """What ``nohup cmd &`` in a script (a shell without job control) does to the command (a ``preexec_fn``)."""
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def test_a_run_under_nohup_in_the_background_goes_on_after_a_hangup_and_a_ctrl_c(tmp_path):
    """It stops on SIGTERM. (SIGINT in the final evaluation was ignored before, in training it stopped the run.)"""
    out = tmp_path / "run"
    command = [sys.executable, "-m", "activeperc_rl.cli", *TINY, "--out", str(out), "--frames", "10000000"]
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, preexec_fn=ignore_hangups_and_ctrl_c
    )
    wait_for_rows(out, 2)
    process.send_signal(signal.SIGHUP)
    process.send_signal(signal.SIGINT)
    rows = rows_logged(out)
    wait_for_rows(out, rows + 3)
    assert process.poll() is None and rows_logged(out) >= rows + 3  # still training
    process.send_signal(signal.SIGTERM)
    output, _ = process.communicate(timeout=120)
    assert process.returncode == 0 and "SIGTERM: finishing this iteration" in output, output
    assert "checkpoint saved" in output and "SIGHUP" not in output and "Ctrl-C" not in output


def catches(pid: int, number: int) -> bool:
    """Whether process ``pid`` has a handler of signal ``number`` (Linux's /proc: SigCgt)."""
    with open(f"/proc/{pid}/status") as status:
        mask = next(line for line in status if line.startswith("SigCgt:")).split()[1]
    return bool(int(mask, 16) >> (number - 1) & 1)


@pytest.mark.parametrize("command", ["train", "evaluate"])
def test_sigterm_while_the_command_starts_is_one_line(tmp_path, command):
    """The console scripts catch SIGTERM before torch loads (their imports take a second or more): one line, exit
    130, and nothing written; before, the process died of the signal with no word."""
    script = (
        f"import sys; from activeperc_rl.commands import {command}; sys.argv[1:] = ['{tmp_path / 'run'}']; "
        f"sys.exit({command}())"
    )
    process = subprocess.Popen(
        [sys.executable, "-c", script],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
        preexec_fn=default_stop_signals,
    )
    deadline = time.monotonic() + 60
    while not catches(process.pid, signal.SIGTERM) and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.002)
    with open(f"/proc/{process.pid}/maps") as maps:
        torch_loaded = "libtorch" in maps.read()
    process.send_signal(signal.SIGTERM)
    output, errors = process.communicate(timeout=60)
    assert not torch_loaded, "the handler came only once torch had loaded"
    prog = {"train": "activeperc-train", "evaluate": "activeperc-eval"}[command]
    assert process.returncode == 130 and errors.strip() == f"{prog}: interrupted", errors
    assert output == "" and os.listdir(tmp_path) == []


def test_the_random_baseline_plays_the_random_policy(tmp_path, capsys, monkeypatch):
    """The final evaluation scores the learned policy, the learned mover with the camera held forward (where a learned
    looker turns it), then the random one; ``activeperc-eval --random`` the latter."""
    played, real = [], evaluate.evaluate

    def spy(config, mover_policy=None, looker=None, *args, **kwargs):
        held = isinstance(looker, FixedLooker)
        played.append("random" if mover_policy is None and looker is None else "held" if held else "learned")
        return real(config, mover_policy, looker, *args, **kwargs)

    monkeypatch.setattr(evaluate, "evaluate", spy)
    monkeypatch.setattr(train_module, "evaluate", spy)
    out = run_cli(tmp_path, "--method", "ia2c", "--frames", "64", "--eval-episodes", "2")
    assert played == ["learned", "held", "random"]
    assert set(json.loads((out / "eval.json").read_text())) >= {"learned", "camera_held", "random"}
    assert "learned, camera held forward: success rate" in capsys.readouterr().out
    assert evaluate.main([str(out), "--episodes", "2", "--random", "--json"]) == 0
    assert evaluate.main([str(out), "--episodes", "2", "--json"]) == 0
    assert played == ["learned", "held", "random", "random", "learned"]
    played.clear()
    run_cli(tmp_path, "--method", "fixed_forward", "--frames", "64", "--eval-episodes", "2", name="ff")
    assert played == ["learned", "random"]  # its camera is held forward already


def test_eval_cli(tmp_path, capsys):
    out = run_cli(tmp_path, "--method", "meta", "--frames", "256", "--eval-episodes", "0")
    capsys.readouterr()
    video = tmp_path / "episode.mp4"
    assert evaluate.main([str(out), "--episodes", "5", "--seed", "2", "--json", "--video", str(video)]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["episodes"] == 5 and 0 <= result["success_rate"] <= 1 and "mean_return" in result
    assert video.stat().st_size > 0
    assert iio.immeta(video)["fps"] == TrainConfig().env.control_hz  # plays in simulated time
    assert evaluate.main([str(out), "--episodes", "1", "--json", "--video", str(video)]) == 0
    length = json.loads(capsys.readouterr().out)["mean_length"]
    assert iio.imread(video).shape == (length + 1, 240, 640, 3)  # the start, then each cycle
    assert evaluate.main([str(out), "--episodes", "5", "--seed", "2"]) == 0  # the same, as one line of text
    line = f"meta: success rate {result['success_rate']:.3f}, mean return {result['mean_return']:.3f} over 5"
    assert capsys.readouterr().out.startswith(line)
    assert evaluate.main([str(out / "checkpoint.pt"), "--episodes", "5", "--seed", "2", "--random", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["policy"] == "random"
    assert evaluate.main([str(tmp_path / "missing")]) == 2
    assert "missing" in capsys.readouterr().err
    for flags, named in (
        (["--video", str(tmp_path / "episode")], "episode"),
        (["--seed", "-1"], "seed=-1"),
    ):
        assert evaluate.main([str(out), "--episodes", "2", *flags]) == 2
        assert named in capsys.readouterr().err
    with pytest.raises(SystemExit):
        evaluate.main([str(out), "--device", "gpu"])
    assert "gpu" in capsys.readouterr().err
    assert evaluate.main([str(out), "--episodes", "2", "--device", "auto", "--json"]) == 0


def test_sigterm_in_the_final_evaluation_stops_like_ctrl_c(tmp_path, capsys, monkeypatch):
    """Outside the training loop (start, final evaluation) SIGTERM aborts as Ctrl-C does: exit 130, one line
    that says how to resume from the kept checkpoint, no ``eval.json``; the handler it replaced is put back."""

    def killed(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(10)
        raise AssertionError("SIGTERM did not stop the evaluation")

    monkeypatch.setattr(train_module, "evaluate", killed)
    before = signal.getsignal(signal.SIGTERM)
    out = tmp_path / "run"
    assert cli.main([*TINY, "--out", str(out), "--method", "fixed_forward", "--frames", "64"]) == 130
    assert "interrupted; its checkpoint is kept: continue with --resume" in capsys.readouterr().err
    assert load_checkpoint(out / "checkpoint.pt")["frames"] >= 64 and not (out / "eval.json").exists()
    assert signal.getsignal(signal.SIGTERM) is before


def test_eval_stops_like_ctrl_c_on_sigterm_and_leaves_no_half_written_video(tmp_path, capsys, monkeypatch):
    """A kill while ``activeperc-eval`` writes its video: exit 130 with a message, neither the video nor its
    temporary file left behind, and the handler it replaced put back."""
    import imageio.v2

    out = run_cli(tmp_path, "--method", "fixed_forward", "--frames", "64", "--eval-episodes", "0")
    capsys.readouterr()

    def killed_while_writing(path, frames, **kwargs):
        Path(path).write_bytes(b"the first half of a video")
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(10)
        raise AssertionError("SIGTERM did not stop the evaluation")

    monkeypatch.setattr(imageio.v2, "mimwrite", killed_while_writing)
    before = signal.getsignal(signal.SIGTERM)
    videos = tmp_path / "videos"
    assert evaluate.main([str(out), "--episodes", "2", "--video", str(videos / "episode.mp4")]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert list(videos.iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) is before


def test_eval_names_what_is_not_a_usable_checkpoint(tmp_path, capsys):
    garbage, foreign, empty = tmp_path / "garbage.pt", tmp_path / "foreign.pt", tmp_path / "empty_run"
    garbage.write_bytes(b"not a checkpoint at all")
    torch.save({"weights": torch.zeros(2)}, foreign)
    empty.mkdir()
    out = run_cli(tmp_path, "--method", "fixed_forward", "--frames", "64", "--eval-episodes", "0")
    damaged = bytearray((out / "checkpoint.pt").read_bytes())
    for i in np.random.default_rng(0).choice(len(damaged) // 2, 200, replace=False) + len(damaged) // 4:
        damaged[i] ^= 0xFF  # 200 bytes flipped in the middle half: weights and optimizer state
    (tmp_path / "flipped.pt").write_bytes(damaged)
    for path, named in (
        (tmp_path / "flipped.pt", "flipped.pt' is damaged: its part 'archive/data/"),
        (garbage, "garbage.pt' cannot be read"),
        (foreign, "foreign.pt' is not an activeperc checkpoint"),
        (empty, "no checkpoint at '" + str(empty / "checkpoint.pt")),
    ):
        assert evaluate.main([str(path)]) == 2
        assert named in capsys.readouterr().err


def test_a_checkpoint_whose_networks_do_not_fit_its_config_is_one_line(tmp_path, capsys):
    out = run_cli(tmp_path, "--method", "fixed_forward", "--frames", "64", "--eval-episodes", "0")
    state = load_checkpoint(out / "checkpoint.pt")
    network = state["config"]["network"] | {"hidden_size": 64}
    save_checkpoint(out / "checkpoint.pt", state | {"config": state["config"] | {"network": network}})
    capsys.readouterr()
    assert evaluate.main([str(out), "--episodes", "2"]) == 2
    err = capsys.readouterr().err
    assert "checkpoint.pt' is unusable: its 'mover_actor' does not fit the config" in err
    assert "size mismatch" in err and "Traceback" not in err
    save_checkpoint(out / "checkpoint.pt", state | {"method": {"weights": 1}})
    assert evaluate.main([str(out), "--episodes", "2"]) == 2
    assert "unusable: it holds no networks" in capsys.readouterr().err


def test_videos_of_odd_sized_views_encode_and_gifs_loop(tmp_path):
    from PIL import Image

    from activeperc_env.render import side_by_side

    frames = [side_by_side(np.zeros((240, 320, 3), np.uint8), np.full((61, 81, 3), 40 * i, np.uint8)) for i in range(3)]
    evaluate._write_video(tmp_path / "odd.mp4", frames, fps=5.0)  # ffmpeg refused odd sides
    assert iio.imread(tmp_path / "odd.mp4").shape == (3, *frames[0].shape)
    evaluate._write_video(tmp_path / "loop.gif", frames, fps=5.0)
    with Image.open(tmp_path / "loop.gif") as gif:
        assert gif.info["loop"] == 0 and gif.info["duration"] == 200 and gif.n_frames == 3


def test_eval_checks_the_video_path_before_it_plays(tmp_path, capsys, monkeypatch):
    out = run_cli(tmp_path, "--method", "fixed_forward", "--frames", "64", "--eval-episodes", "0")
    capsys.readouterr()

    def no_play(*args, **kwargs):
        raise AssertionError("the episodes were played before the video path was checked")

    monkeypatch.setattr(evaluate, "make_env", no_play)
    (tmp_path / "taken.mp4").mkdir()
    (tmp_path / "file").write_text("")
    for video, named in (
        (tmp_path / "taken.mp4", "taken.mp4' is a directory, not a file"),
        (tmp_path / "file" / "x.mp4", f"{str(tmp_path / 'file')!r} is a file, not a directory"),
    ):
        assert evaluate.main([str(out), "--episodes", "2", "--video", str(video)]) == 2
        assert named in capsys.readouterr().err


def test_evaluate_names_what_it_cannot_play():
    from activeperc_rl.models import FixedLooker

    for config in (None, {"env": {}}):
        with pytest.raises(TypeError, match=f"config={config!r} is invalid: expected a TrainConfig"):
            evaluate.evaluate(config, episodes=1)
    with pytest.raises(ValueError, match="a looker was given without a mover_policy"):
        evaluate.evaluate(TrainConfig(), None, FixedLooker(), episodes=1)
    with pytest.raises(TypeError, match="mover_policy='x' is invalid"):
        evaluate.evaluate(TrainConfig(), "x", episodes=1)


def test_eval_is_reproducible_and_held_out(tmp_path, capsys, monkeypatch):
    config = TrainConfig.from_options(env={"max_cycles": 10})
    made = []
    monkeypatch.setattr(evaluate, "make_env", lambda *a, **kw: made.append(make_env(*a, **kw)) or made[-1])
    a = evaluate.evaluate(config, episodes=6, seed=4)
    assert len(made) == 1 and (made[0].episode_seeds % 2 == 1).all()  # the rooms played held-out layouts
    assert capsys.readouterr().err == ""
    b = evaluate.evaluate(config, episodes=6, seed=4, progress=True)  # the bar changes nothing but stderr
    assert a == b and a["episodes"] == 6 and a["mean_length"] <= 10
    assert "evaluating" in capsys.readouterr().err
    train_env, eval_env = make_env(3, seed=0), make_env(3, seed=0, split="eval")
    train_env.reset(), eval_env.reset()
    assert (train_env.episode_seeds % 2 == 0).all() and (eval_env.episode_seeds % 2 == 1).all()
    train_env.close(), eval_env.close()


def test_a_diverged_run_ends_with_one_line_and_keeps_its_checkpoint(tmp_path):
    """Learning that blows up (NaN or infinite logits) ends the run with the documented one-line error, status 1."""
    out = tmp_path / "run"
    done = subprocess.run(
        [sys.executable, "-m", "activeperc_rl.cli", "--lr", "1e10", "--num-envs", "2", "--frames", "20000",
         "--eval-episodes", "0", "--out", str(out), "--no-progress"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr and "activeperc-train: error: training failed at iteration" in done.stderr
    assert "is kept in" in done.stderr and (out / "checkpoint.pt").is_file()


def test_a_full_disk_ends_with_one_line_naming_the_file(tmp_path):
    """torch's writer raises a RuntimeError of its own when a write fails; the checkpoint is written with Python's
    file I/O instead, so a full disk (here: a file-size limit) is the one-line OSError, status 1."""
    import resource

    def small_files():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit then fails with EFBIG
        resource.setrlimit(resource.RLIMIT_FSIZE, (1_000_000, 1_000_000))

    done = subprocess.run(
        [sys.executable, "-m", "activeperc_rl.cli", "--num-envs", "2", "--frames", "64", "--eval-episodes", "0",
         "--out", str(tmp_path / "run"), "--no-progress"],
        capture_output=True, text=True, timeout=300, preexec_fn=small_files,
    )  # fmt: skip
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr and "checkpoint.pt" in done.stderr, done.stderr
    assert done.stderr.count("\n") == 1, done.stderr
