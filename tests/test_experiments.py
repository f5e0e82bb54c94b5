"""The scripts of experiments/ outside fig1: a bad argument is one line naming it, before any work."""

import math
import subprocess
import sys
from pathlib import Path

import pytest

EXPERIMENTS = Path(__file__).resolve().parent.parent / "experiments"


@pytest.mark.parametrize(
    ("script", "args", "message"),
    [
        ("motion_profile.py", ["--cycles", "0"], "--cycles must be >= 1, got 0"),
        ("motion_profile.py", ["--random-cycles", "0"], "--random-cycles must be >= 32"),
        ("goal_visibility.py", ["--min-pixels", "-1"], "--min-pixels must be >= 1, got -1"),
        ("goal_visibility.py", ["--batch", "0"], "--batch must be >= 1, got 0"),
        ("tile_shading.py", ["--rooms", "0"], "--rooms must be >= 1, got 0"),
        ("scripted_looker_training.py", ["--frames", "0"], "--frames and --episodes must be >= 1"),
        ("scripted_looker_training.py", ["--looker", "peek"], "invalid choice: 'peek'"),
        ("look_values.py", ["RUN", "--cycles", "0"], "--rooms and --cycles must be >= 1"),
        ("pan_vs_bearing.py", ["RUN", "--episodes", "0"], "--episodes=0 must be >= 1"),
        ("memory_mover_training.py", ["--memory", "0"], "--frames, --episodes and --memory must be >= 1"),
        ("best_look_labels.py", ["RUN", "--bin", "0"], "--bin must be >= 1, got 0"),
        ("looker_refit.py", ["RUN", "--lr", "0"], "--rooms, --cycles and --batch must be >= 1 and every --lr > 0"),
        ("looker_refit.py", ["RUN", "--fresh-frames", "0"], "--fresh-frames [0]: expected views in 1 .. 16"),
        ("looker_swap.py", ["RUN", "--episodes", "0"], "--episodes must be >= 1, got 0"),
        ("looker_swap.py", ["no-such-run"], "'no-such-run': no checkpoint.pt there"),
        ("looker_swap.py", ["RUN", "--lookers-of", "other"], "'RUN', 'other': no checkpoint.pt there"),
        ("pretrained.py", ["RUN", "--episodes", "0"], "--episodes must be >= 1, got 0"),
        ("pretrained.py", ["no-such-run"], "'no-such-run' holds no run"),
    ],
)
def test_a_bad_argument_is_named(script, args, message):
    done = subprocess.run(
        [sys.executable, str(EXPERIMENTS / script), *args], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 2, done.stderr
    assert message in done.stderr and "Traceback" not in done.stderr


def test_tile_shading_compares_every_tile_with_one_room():
    done = subprocess.run(
        [sys.executable, str(EXPERIMENTS / "tile_shading.py"), "--episodes", "1", "--cycles", "10", "--rooms", "4"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("40 views (4 tiles, 10 states, 80x60 pixels) against one room's")
    assert "views that differ at all:" in done.stdout and "by more than one level" in done.stdout


def test_a_mover_trains_with_a_scripted_looker_in_its_loop():
    done = subprocess.run(
        [sys.executable, str(EXPERIMENTS / "scripted_looker_training.py"), "--looker", "scan", "--frames", "512",
         "--episodes", "2", "--recipe", "default", "--bearing-bins", "30"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    import json

    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["looker"] == "scan" and result["frames"] >= 512 and result["eval"]["episodes"] == 2
    assert (result["recipe"], result["bearing_bins"]) == ("default", 30)


def test_a_mover_with_memory_trains_with_a_scripted_looker_in_its_loop():
    done = subprocess.run(
        [sys.executable, str(EXPERIMENTS / "memory_mover_training.py"), "--looker", "scan", "--frames", "512",
         "--episodes", "2", "--memory", "16", "--version", "2"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    import json

    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["looker"] == "scan" and result["memory"] == 16 and 0 <= result["success"] <= 1


def test_the_memory_movers_loss_replays_the_rollout_as_it_was_collected(monkeypatch):
    """In the loss, the GRU runs over each room's rollout from the state it was collected with, reset where an
    episode starts: the log-probabilities of the actions are those of the collection, across episode ends and from
    one rollout to the next."""
    import torch
    from torchrl.collectors import Collector
    from torchrl.modules import set_recurrent_mode

    from activeperc_rl.recipe import TrainConfig

    monkeypatch.syspath_prepend(str(EXPERIMENTS))
    from memory_mover_training import MOVER, memory_actor_critic, memory_env

    config = TrainConfig.from_options(
        method="fixed_forward", channels=(8,), hidden_size=32, env={"version": 2, "max_cycles": 10}
    )
    actor, _, gru = memory_actor_critic(config, 16)
    collector = Collector(memory_env(config, "scan", gru, 4, "train"), actor, frames_per_batch=64, total_frames=192)
    starts = 0
    try:
        for rollout in collector:
            rollout = rollout.reshape(4, 16)
            starts += int(rollout.get("is_init")[:, 1:].sum())
            with set_recurrent_mode(True), torch.no_grad():
                replayed = actor.get_dist(rollout.exclude((MOVER, "action"))).log_prob(rollout.get((MOVER, "action")))
            torch.testing.assert_close(replayed, rollout.get((MOVER, "action_log_prob")))
    finally:
        collector.shutdown()
    assert starts > 0  # episodes of 10 cycles started inside the 16-cycle rollouts


def test_look_values_tables_a_meta_runs_critic_and_looker(tmp_path):
    from activeperc_rl import cli

    out = tmp_path / "run"
    tiny = ["--num-envs", "4", "--rollout-length", "8", "--channels", "8", "--hidden-size", "32", "--no-progress"]
    assert cli.main([*tiny, "--frames", "96", "--eval-episodes", "0", "--bearing-bins", "12", "--out", str(out)]) == 0
    done = subprocess.run(
        [sys.executable, str(EXPERIMENTS / "look_values.py"), str(out), "--rooms", "4", "--cycles", "20", "--csv",
         str(tmp_path / "v.csv")],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    import csv

    with open(tmp_path / "v.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert rows[0]["goal_in_s_bar"] == "not in view" and rows[0]["greedy_hold"] == "1.0000"  # the printed table's
    assert len(rows) == len(lines) - 3 and all(row["run"] == str(out) for row in rows)
    assert lines[0].endswith("epsilon 0.3") and "Q(left)-Q(hold)" in lines[1]
    greedy, probs = lines[2].split("|")[-2:]
    assert lines[2].startswith("not in view") and greedy.split() == ["0.00", "1.00", "0.00"]  # untrained phi2 holds
    assert float(probs.split()[1]) > 0.9 and math.isclose(sum(map(float, probs.split())), 1, abs_tol=0.015)


@pytest.mark.parametrize("method", ["meta", "ia2c", "joint"])
def test_looker_swap_scores_a_runs_mover_with_each_looker(tmp_path, method):
    import csv

    from activeperc_rl import cli

    out, table = tmp_path / "run", tmp_path / "swap.csv"
    tiny = ["--num-envs", "4", "--rollout-length", "8", "--channels", "8", "--hidden-size", "32", "--no-progress"]
    train = [*tiny, "--method", method, "--frames", "96", "--eval-episodes", "0", "--max-cycles", "10"]
    assert cli.main([*train, "--out", str(out)]) == 0
    done = subprocess.run(
        [sys.executable, str(EXPERIMENTS / "looker_swap.py"), str(out), "--episodes", "4", "--csv", str(table)],
        capture_output=True, text=True, timeout=300, cwd=EXPERIMENTS.parent,
    )  # fmt: skip
    if method == "joint":  # no looker of its own to swap
        assert done.returncode == 1 and "a joint run, without a looker of its own" in done.stderr
        assert not table.exists()
        return
    assert done.returncode == 0, done.stderr
    rows = list(csv.DictReader(open(table)))
    lookers = ["phi1", "phi1 in view, random pan out of view", "phi1 in view, hold out of view"]
    lookers += ["track in view, phi1 out of view", "track"]
    lookers.append("critic's best look")
    assert [r["looker"] for r in rows] == lookers and all(r["episodes"] == "4" for r in rows)
    assert all(0 <= float(r["success_rate"]) <= 1 for r in rows)
    assert len(done.stdout.splitlines()) == 1 + len(lookers)


def test_the_best_look_looker_takes_the_look_whose_view_the_critic_values_most():
    """A critic that values a view by its pan: the looker pans left (positive pans) until the limit, then holds."""
    import torch
    from tensordict.nn import TensorDictModule

    from activeperc_env import EnvConfig
    from activeperc_env.core import HOLD, LOOKER_ACTIONS
    from activeperc_rl.envs import LOOKER, MOVER, make_env
    from activeperc_rl.models import RandomPolicy

    sys.path.insert(0, str(EXPERIMENTS))
    from looker_swap import BestLook

    pan = TensorDictModule(
        lambda image, pan: pan.sum(-1, keepdim=True),
        [(MOVER, "observation", "image"), (MOVER, "observation", "pan")],
        ["state_value"],
    )
    env = make_env(3, looker=BestLook(pan), look_views=True, seed=0, config=EnvConfig(max_cycles=40))
    torch.manual_seed(0)
    rollout = env.rollout(30, RandomPolicy((MOVER,)), break_when_any_done=False)
    env.close()
    looks, pans = rollout["next", LOOKER, "action"], rollout["next", LOOKER, "observation", "pan"][..., -1]  # as seen
    limit = env.config.pan_range * torch.pi / 180
    at_limit = pans >= limit - 1e-6
    assert at_limit.any() and (~at_limit).any()
    assert (looks[~at_limit] == LOOKER_ACTIONS.index("pan_left")).all() and (looks[at_limit] == HOLD).all()


def test_looker_swap_swaps_the_lookers_of_meta_and_ia2c_runs(tmp_path):
    import csv

    from activeperc_rl import cli

    tiny = ["--num-envs", "4", "--rollout-length", "8", "--channels", "8", "--hidden-size", "32", "--no-progress"]
    tiny += ["--frames", "96", "--eval-episodes", "0", "--max-cycles", "10"]
    runs = {name: tmp_path / name for name in ("meta", "ia2c", "ia2c_fov100")}
    for name, out in runs.items():
        fov = ["--fov", "100"] if name.endswith("fov100") else []
        assert cli.main([*tiny, *fov, "--method", name.split("_")[0], "--out", str(out)]) == 0
    script, table = [sys.executable, str(EXPERIMENTS / "looker_swap.py")], tmp_path / "swap.csv"
    both = [str(runs["meta"]), str(runs["ia2c"])]
    done = subprocess.run(
        [*script, *both, "--episodes", "2", "--lookers-of", *both, "--csv", str(table)],
        capture_output=True, text=True, timeout=300, cwd=EXPERIMENTS.parent,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    rows = list(csv.DictReader(open(table)))
    assert [(r["run"], r["looker"]) for r in rows if r["looker"].startswith("looker of")] == [
        (both[0], f"looker of {both[1]}"),
        (both[1], f"looker of {both[0]}"),
    ]
    sys.path.insert(0, str(EXPERIMENTS))
    from looker_swap import LOOKERS

    assert len(rows) == 2 * (len(LOOKERS) + 1)  # each mover: every looker, then the other run's
    done = subprocess.run(
        [*script, both[0], "--episodes", "2", "--lookers-of", str(runs["ia2c_fov100"])],
        capture_output=True, text=True, timeout=300, cwd=EXPERIMENTS.parent,
    )  # fmt: skip
    assert done.returncode == 1 and f"{runs['ia2c_fov100']} was trained in another room than {both[0]}" in done.stderr


def test_looker_refit_scores_a_meta_runs_lookers_and_refitted_copies(tmp_path):
    import csv

    import torch

    from activeperc_env.core import HOLD
    from activeperc_rl import cli
    from activeperc_rl.recipe import make_method
    from activeperc_rl.runtime.checkpoint import load_checkpoint, load_run_config, restore_method

    sys.path.insert(0, str(EXPERIMENTS))
    import looker_refit

    out, table = tmp_path / "run", tmp_path / "refit.csv"
    tiny = ["--num-envs", "4", "--rollout-length", "8", "--channels", "8", "--hidden-size", "32", "--no-progress"]
    assert cli.main([*tiny, "--frames", "96", "--eval-episodes", "0", "--bearing-bins", "12", "--out", str(out)]) == 0
    argv = [str(out), "--rooms", "4", "--cycles", "12", "--steps", "2", "--batch", "16", "--lr", "1e-3"]
    fresh = ["--fresh-frames", "1", "3", "--fresh-steps", "3"]
    assert looker_refit.main([*argv, *fresh, "--episodes", "2", "--csv", str(table)]) == 0
    rows = list(csv.DictReader(table.open()))
    assert [(r["looker"], r["steps"], r["lr"]) for r in rows] == [
        ("phi2", "0", ""),
        ("phi1", "0", ""),
        ("phi2", "2", "0.001"),
        ("fresh, 1 view", "3", "0.001"),
        ("fresh, 3 views", "3", "0.001"),
    ]
    assert all(r["episodes"] == "2" and float(r["success_rate"]) in (0.0, 0.5, 1.0) for r in rows)
    config = load_run_config(out)
    method = make_method(config, torch.device("cpu"), start=False)
    restore_method(method, load_checkpoint(out / "checkpoint.pt"), out)
    _, labels, _ = looker_refit.labelled_looks(method, config, 4, 12, "eval", 0)
    assert int(rows[0]["cycles"]) == len(labels) > 0
    # the barely trained phi2 still holds: its greedy look is the label where 'hold' is
    assert rows[0]["agreement"] == f"{(labels == HOLD).float().mean():.3f}"


def test_pan_vs_bearing_plays_the_evaluations_episodes(tmp_path):
    import numpy as np

    from activeperc_rl import cli
    from activeperc_rl.evaluate import evaluate, load_policy

    sys.path.insert(0, str(EXPERIMENTS))
    import pan_vs_bearing

    out = tmp_path / "run"
    tiny = ["--num-envs", "4", "--rollout-length", "8", "--channels", "8", "--hidden-size", "32", "--no-progress"]
    train = [*tiny, "--frames", "96", "--eval-episodes", "0", "--max-cycles", "12", "--seed", "3", "--out", str(out)]
    train += ["--frame-stack", "2", "--bearing-bins", "0"]  # the goal is looked for in the latest view
    assert cli.main(train) == 0
    argv = [str(out), "--episodes", "6", "--figure", str(tmp_path / "f.png"), "--csv", str(tmp_path / "r.csv")]
    assert pan_vs_bearing.main(argv) == 0
    config, mover, looker = load_policy(out)
    learned = pan_vs_bearing.play(config, mover, looker, 6, seed=3)
    held = pan_vs_bearing.play(config, mover, pan_vs_bearing.FixedLooker(), 6, seed=3)
    # the run's own evaluation (its seed: the same episodes and sampling), with a record of each of its cycles
    assert learned["success_rate"] == evaluate(config, mover, looker, episodes=6, seed=3)["success_rate"]
    assert len(learned["pan"]) == len(learned["seen"]) == round(learned["mean_length"] * 6) <= 6 * 12
    learned_row = (tmp_path / "r.csv").read_text().splitlines()[1].split(",")
    assert learned_row[1:4] == ["learned", "6", f"{learned['success_rate']:.3f}"]  # main() played the same
    assert held["episodes"] == 6 and not held["looked"].any() and (held["pan"] == 0).all()
    assert len(held["pan"]) == round(held["mean_length"] * 6)
    assert np.abs(learned["bearing"]).max() <= 180 and np.abs(learned["pan"]).max() <= config.env.pan_range + 1e-3
    rows = (tmp_path / "r.csv").read_text().splitlines()
    assert rows[0].startswith("run,looker,episodes") and len(rows) == 3 and (tmp_path / "f.png").stat().st_size > 0


def test_best_look_labels_bins_a_runs_shares_and_refuses_a_run_without_them(tmp_path, capsys):
    sys.path.insert(0, str(EXPERIMENTS))
    import best_look_labels

    header = "frames,e1_pan_rate,looker_entropy,best_look_agreement,best_look_left,best_look_right\n"
    (tmp_path / "metrics.csv").write_text(header + "100,0.1,1.0,0.5,0.2,0.3\n200,0.3,0.8,0.7,0.4,0.1\n300,0,0,1,0,0\n")
    out = tmp_path / "labels.csv"
    assert best_look_labels.main([str(tmp_path), "--bin", "250", "--csv", str(out)]) == 0
    first, second = best_look_labels.binned(tmp_path, 250)
    assert (first["frames"], first["iterations"]) == ("100-200", 2) and first["e1_pan_rate"] == pytest.approx(0.2)
    assert first["agreement"] == pytest.approx(0.6) and first["best_hold"] == pytest.approx(0.5)
    assert second["best_hold"] == 1.0 and out.read_text().count("\n") == 3
    (tmp_path / "metrics.csv").write_text(header + "100,0.1,1.0,,,\n200,0.3,0.8,0.7,0.4,0.1\n")
    (blank_and_logged,) = best_look_labels.binned(tmp_path, 250)  # a row of an older log is blank in the shares
    assert math.isnan(blank_and_logged["agreement"]) and blank_and_logged["iterations"] == 2
    (tmp_path / "metrics.csv").write_text(header + "100,0.1,1.0,nan,nan,nan\n")
    with pytest.raises(SystemExit, match="has no best-look shares"):
        best_look_labels.main([str(tmp_path)])
