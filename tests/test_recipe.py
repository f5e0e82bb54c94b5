"""The training recipe: the defaults are the recipe that works, options live in their parts' sections, the named
presets ship with the package, and runs saved before the sections existed resume and evaluate as they did."""

import ast
import csv
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from activeperc_env import EnvConfig
from activeperc_env.rooms import DEFAULT
from activeperc_rl import cli
from activeperc_rl.config import A2CConfig, RunConfig
from activeperc_rl.methods import METHODS, IA2CConfig, MetaConfig
from activeperc_rl.models import NetworkConfig
from activeperc_rl.recipe import LEGACY_DEFAULTS, TrainConfig, preset
from activeperc_rl.runtime import portable
from activeperc_rl.runtime.checkpoint import load_run_config

ROOT = Path(__file__).resolve().parent.parent
LEGACY_RUN = Path(__file__).resolve().parent / "fixtures" / "run_0a7f32c"
"""A run saved by the code of commit 0a7f32c (flat config.yaml, room v1, the defaults of that day):
``activeperc-train --portable --method meta --num-envs 2 --rollout-length 8 --channels 4 --hidden-size 8
--learner-threads 1 --torch-threads 1 --eval-episodes 6 --width 16 --height 12 --num-obstacles 1 --goal-distance 2.5
--forward-speed 3.0 --max-cycles 30 --checkpoint-every 1000 --frames 96`` (``saved/``), then, by that code too,
``activeperc-train --resume --out saved --frames 192``: its metrics, evaluation and weights (``resumed_*``)."""


def test_the_defaults_are_the_recipe_that_works_in_the_default_room():
    config = TrainConfig()
    assert config.method == "meta" and config.env == EnvConfig() and config.env.version == DEFAULT
    assert (config.options.looker_credit, config.options.looker_lr, config.network.bearing_bins) == (
        "best_look", 3e-4, 30
    )  # fmt: skip
    assert (config.run.frames, config.run.num_envs, config.run.rollout_length) == (400_000, 32, 8)
    assert config.a2c.lr_schedule == "linear" and config.run.eval_episodes == 100
    # the README's command before the recipe became the defaults
    five_flags = ["--version", "3", "--looker-credit", "best_look", "--looker-lr", "3e-4", "--bearing-bins", "30"]
    shape = ["--frames", "400000", "--num-envs", "32", "--rollout-length", "8", "--lr-schedule", "linear"]
    args = cli.build_parser().parse_args(["--preset", "pilot", *shape, *five_flags])
    assert cli.config_from_args(args) == config == cli.config_from_args(cli.build_parser().parse_args([]))


def test_each_option_lives_in_its_section():
    config = TrainConfig.from_options(method="ia2c", frames=1000, lr=1e-3, bearing_bins=0, looker_lr=1e-4, fov=100)
    assert config.run == RunConfig(frames=1000) and config.a2c == A2CConfig(lr=1e-3)
    assert config.network == NetworkConfig(bearing_bins=0) and config.options == IA2CConfig(looker_lr=1e-4)
    assert config.env == EnvConfig(fov=100)
    assert TrainConfig.from_dict(config.to_dict()) == config == TrainConfig.from_saved(config.to_dict())
    assert config.replace(method="meta").options == MetaConfig()  # another method starts from its own defaults
    with pytest.raises(ValueError, match="unknown training option 'colour'"):
        config.replace(colour="red")


@pytest.mark.parametrize("name", ["paper", "pilot"])
def test_the_named_presets_load_for_every_method(name):
    values = preset(name)
    for method in METHODS:
        config = TrainConfig.from_dict(values, {"method": method})
        assert config.network.bearing_bins == 0
        if method in ("meta", "ia2c"):
            assert config.options.looker_lr == 3e-5
    meta = TrainConfig.from_dict(values)
    assert meta.options.looker_credit == "trajectory"
    assert meta.options.mover_rollouts == ("d1" if name == "paper" else "all")  # the paper's; the pilot's default
    assert meta.env.version == (0 if name == "pilot" else DEFAULT)
    with pytest.raises(ValueError, match=r"preset 'papr' does not exist: the presets are \['paper', 'pilot'\]"):
        preset("papr")


def test_the_pilot_preset_is_the_figure_1_pilots_runs():
    """Each run of the committed pilot (experiments/fig1/configs/v0/) is the pilot preset with its method, field of
    view and epsilon, and nothing else."""
    for path in sorted((ROOT / "experiments/fig1/configs/v0").glob("*.yaml")):
        config = TrainConfig.from_dict(yaml.safe_load(path.read_text()))
        method, fov = path.stem.rsplit("_fov", 1)
        flags = {"method": config.method, "fov": float(fov)}
        if method.startswith("meta_eps"):
            flags["epsilon"] = float(method.removeprefix("meta_eps"))
        assert config.replace(frames=300_000) == TrainConfig.from_dict(preset("pilot"), flags), path.name


@pytest.mark.parametrize(
    "written, flags, named",
    [
        ({"run": {"frames": 3.7}}, {"frames": 64}, "run.frames=3.7"),
        ({"env": {"fov": 500}}, {"fov": 60}, "fov=500"),
        ({"meta": {"epsilon": 7}}, {"epsilon": 0.1}, "meta.epsilon=7"),
        ({"meta": {"epsilon": 7}}, {"method": "ia2c"}, "meta.epsilon=7"),
    ],
)
def test_a_preset_is_checked_as_written_where_a_flag_replaces_a_value(written, flags, named):
    with pytest.raises(ValueError, match=re.escape(named)):
        TrainConfig.from_dict(written, flags)


def test_a_flat_config_saved_before_the_sections_is_read_with_the_defaults_of_its_day():
    saved = yaml.safe_load((LEGACY_RUN / "saved" / "config.yaml").read_text())
    config = TrainConfig.from_saved(saved)
    assert config.env.version == 1 and config.options.looker_credit == "trajectory"
    assert (config.run.num_envs, config.network.channels, config.options.looker_lr) == (2, (4,), 3e-5)
    bare = {"method": "ia2c", "epsilon": 0.3, "env": {"fov": 100}}  # a run saved before most options existed
    old = TrainConfig.from_saved(bare)
    assert old.env.version == 0 and old.run.frames == LEGACY_DEFAULTS["frames"]
    assert old.options.looker_lr == 3e-5 and old.network.bearing_bins == 0  # epsilon, not ia2c's, is dropped
    assert not config.a2c.reuse_features and not old.a2c.reuse_features  # they ran TorchRL's A2CLoss as it ships


def test_a_run_saved_by_section_before_an_option_existed_reads_the_value_it_ran_with():
    saved = TrainConfig.from_dict({}).to_dict()
    assert TrainConfig.from_saved(saved).a2c.reuse_features
    del saved["a2c"]["reuse_features"], saved["a2c"]["lr_schedule"]
    assert TrainConfig.from_saved(saved).a2c.reuse_features is False
    assert TrainConfig.from_saved(saved).a2c.lr_schedule == "constant"
    assert TrainConfig.from_saved(saved | {"a2c": None}).a2c.reuse_features is False
    with pytest.raises(ValueError, match="'a2c' must be a mapping"):
        TrainConfig.from_saved(saved | {"a2c": 3})


@pytest.mark.skipif(not portable.has_avx2(), reason="the fixture's run is portable: its kernels are pinned to AVX2")
def test_a_run_saved_before_this_change_resumes_and_evaluates_exactly_as_before(tmp_path):
    run = tmp_path / "run"
    shutil.copytree(LEGACY_RUN / "saved", run)
    assert load_run_config(run).env.version == 1  # not the default room
    command = [sys.executable, "-m", "activeperc_rl.cli", "--resume", "--out", str(run), "--frames", "192"]
    subprocess.run(command, check=True, capture_output=True, text=True)
    timings = ("time_s", "fps")
    with open(run / "metrics.csv", newline="") as ours, open(LEGACY_RUN / "resumed_metrics.csv", newline="") as theirs:
        rows = [
            [{k: v for k, v in row.items() if k not in timings} for row in csv.DictReader(f)] for f in (ours, theirs)
        ]
    assert len(rows[0]) == 4 and rows[0] == rows[1]
    assert json.loads((run / "eval.json").read_text()) == json.loads((LEGACY_RUN / "resumed_eval.json").read_text())
    sys.path.insert(0, str(Path(__file__).parent))
    from golden import training_trace

    assert training_trace(run)["weights"] == (LEGACY_RUN / "resumed_weights.txt").read_text().strip()


def test_no_import_circle_in_the_training_package():
    """Every module of activeperc_rl imports only modules that do not import it back, directly or not."""
    package = ROOT / "activeperc_rl"
    graph = {}
    for path in package.rglob("*.py"):
        name = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
        imported = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("activeperc_rl"):
                imported |= {node.module} | {f"{node.module}.{alias.name}" for alias in node.names}
            elif isinstance(node, ast.Import):
                imported |= {alias.name for alias in node.names if alias.name.startswith("activeperc_rl")}
        graph[name] = imported
    graph = {name: {m for m in imported if m in graph and m != name} for name, imported in graph.items()}

    def reaches(start, target, seen=()):
        return any(m == target or (m not in seen and reaches(m, target, (*seen, m))) for m in graph[start])

    circles = [name for name in graph if name != "activeperc_rl" and reaches(name, name)]
    assert circles == [], circles
