"""Policy files and the pretrained policies shipped in the package."""

import json

import pytest
import torch

import activeperc_rl
from activeperc_rl import cli, evaluate
from activeperc_rl.policies import PRETRAINED, WEIGHTS, load_policy_file, read_policy_file, save_policy
from activeperc_rl.recipe import TrainConfig

TINY = [
    "--num-envs", "4", "--rollout-length", "8", "--max-cycles", "12", "--channels", "8",
    "--hidden-size", "32", "--eval-episodes", "0", "--no-progress", "--frames", "256",
]  # fmt: skip


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "meta"
    assert cli.main([*TINY, "--out", str(out)]) == 0
    return out


@pytest.mark.parametrize("name", PRETRAINED)
def test_a_pretrained_policy_is_the_default_recipe_and_beats_random_play(name):
    """Each shipped policy loads with one call, was trained by the default recipe at its field of view, and on 16
    held-out layouts reaches the goal far more often than random play (about 0.6 against 0.1 on 100)."""
    config, mover_policy, looker = activeperc_rl.pretrained(name)
    default = TrainConfig().replace(fov=float(name.removeprefix("fov")))
    for part in ("method", "options", "a2c", "network", "env"):
        assert getattr(config, part) == getattr(default, part), f"{name} was not trained by today's default {part}"
    learned = evaluate.evaluate(config, mover_policy, looker, episodes=16, seed=0)
    random_play = evaluate.evaluate(config, None, None, episodes=16, seed=0)
    assert learned["success_rate"] >= random_play["success_rate"] + 0.25, (learned, random_play)
    assert read_policy_file(WEIGHTS / f"{name}.pt")["trained_by"] == PRETRAINED[name]


def test_activeperc_eval_plays_a_pretrained_policy(tmp_path, capsys):
    video = tmp_path / "episode.gif"
    assert evaluate.main(["--pretrained", "fov60", "--episodes", "1", "--json", "--video", str(video)]) == 0
    assert json.loads(capsys.readouterr().out)["policy"] == "meta" and video.stat().st_size > 0
    for argv, named in (
        ([], "either RUN or --pretrained"),
        (["--pretrained", "fov60", str(tmp_path)], "either RUN or --pretrained"),
        (["--pretrained", "fov90"], "invalid choice: 'fov90'"),
    ):
        with pytest.raises(SystemExit):
            evaluate.main(argv)
        assert named in capsys.readouterr().err
    with pytest.raises(ValueError, match="'fov90' is unknown"):
        activeperc_rl.pretrained("fov90")


def test_a_saved_policy_acts_as_its_run_does(tiny_run, tmp_path, capsys):
    """A policy file holds the deployed networks alone (meta: the mover's actor and phi1), in half precision; loaded,
    its weights are the run's rounded, and activeperc-eval reads it."""
    path = tmp_path / "policy.pt"
    about = save_policy(tiny_run, path, trained_by="a tiny run")
    assert about["modules"] == ["mover_actor", "phi1"] and about["trained_by"] == "a tiny run"
    saved = read_policy_file(path)
    assert all(t.dtype == torch.float16 for m in saved["modules"].values() for t in m.values() if t.is_floating_point())
    run = evaluate.load_policy(tiny_run)
    shipped = load_policy_file(path)
    assert run[0] == shipped[0]
    for trained, loaded in zip(run[1:], shipped[1:], strict=True):
        pairs = list(zip(trained.parameters(), loaded.parameters(), strict=True))
        assert pairs and all(torch.equal(a.half().float(), b) for a, b in pairs)
    capsys.readouterr()
    assert evaluate.main([str(path), "--episodes", "2", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["episodes"] == 2


def test_a_damaged_or_foreign_policy_file_is_refused_naming_it(tiny_run, tmp_path, capsys):
    path = tmp_path / "policy.pt"
    save_policy(tiny_run, path)
    data = bytearray(path.read_bytes())
    middle = len(data) // 2
    data[middle : middle + 200] = bytes(b ^ 0xFF for b in data[middle : middle + 200])
    damaged = tmp_path / "damaged.pt"
    damaged.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="damaged.pt' is damaged"):
        load_policy_file(damaged)
    assert evaluate.main([str(damaged), "--episodes", "1"]) == 2
    assert "damaged.pt' is damaged" in capsys.readouterr().err
    foreign = tmp_path / "foreign.pt"
    torch.save({"weights": torch.zeros(3)}, foreign)
    with pytest.raises(ValueError, match="not an activeperc policy file"):
        load_policy_file(foreign)
    with pytest.raises(ValueError, match="no policy file"):
        load_policy_file(tmp_path / "missing.pt")
    saved = read_policy_file(path)
    for name, broken in (
        ("no_config", {k: v for k, v in saved.items() if k != "config"}),
        ("bad_method", saved | {"config": saved["config"] | {"method": "nope"}}),
    ):
        torch.save(broken, tmp_path / f"{name}.pt")
        assert evaluate.main([str(tmp_path / f"{name}.pt"), "--episodes", "1"]) == 2
        assert f"{name}.pt" in capsys.readouterr().err
