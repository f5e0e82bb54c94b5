"""Invalid configuration values are refused with a message that names them."""

import dataclasses
import pydoc

import gymnasium
import numpy as np
import pytest

import activeperc_env
from activeperc_env.config import EnvConfig, field_docs
from activeperc_env.rooms import DEFAULT


@pytest.mark.parametrize(
    "field, value",
    [
        ("fov", 0),
        ("fov", 200),
        ("width", 4),
        ("height", 60.5),
        ("num_obstacles", -1),
        ("num_obstacles", 7),
        ("goal_distance", 2.0),
        ("goal_distance", 5.0),
        ("max_cycles", 0),
        ("max_cycles", 10**30),  # episodes that would never end
        ("turn_speed", 90),  # the default room's base never turns
        ("pan_range", 190),
        ("pan_step", 0),
        ("control_hz", 0),
        ("control_hz", 30),  # 1.67 physics steps of 20 ms
        ("control_hz", 150),
        ("looker_reward", "mine"),
        ("fov", "60"),
        ("fov", None),
        ("max_cycles", True),
        ("width", 80.0),
        ("looker_reward", 3),
        ("range_rays", -1),
        ("range_rays", 65),
        ("range_rays", 1.5),
        ("range_max", 0.1),
        ("range_max", "2"),
        ("version", 4),
        ("version", "1"),
        ("heading_spread", -1),
        ("heading_spread", 181),
        ("version", True),
    ],
)
def test_invalid_value_names_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        EnvConfig(**{field: value})


@pytest.mark.parametrize(
    ("version", "hz", "steps"),
    [(0, 200, 1), (0, 200 / 3, 3), (0, 66.67, 3), (0, 5, 40), (0, 4.0, 50), (0, 0.5, 400)]
    + [(1, 50, 1), (1, 50 / 3, 3), (1, 5, 10), (1, 2.5, 20), (1, 0.5, 100)],
)
def test_control_period_is_whole_physics_steps(version, hz, steps):
    assert activeperc_env.Simulator(EnvConfig(control_hz=hz, version=version)).substeps == steps


@pytest.mark.parametrize(("version", "hz"), [(1, 40), (1, 100), (1, 3), (0, 300), (0, 3)])
def test_a_control_period_of_part_of_a_physics_step_is_named(version, hz):
    with pytest.raises(ValueError, match=f"control_hz={float(hz)!r} is invalid.*v{version} room"):
        EnvConfig(control_hz=hz, version=version)


def test_unknown_option_is_named():
    for error in (ValueError, TypeError):  # TypeError as for any unexpected keyword argument
        with pytest.raises(error, match="unexpected keyword argument 'colour': not an env option"):
            activeperc_env.parallel_env(colour="red")
    with pytest.raises(ValueError, match="unexpected keyword arguments 'a', 'b': not env options"):
        EnvConfig.from_kwargs(b=1, a=2)
    with pytest.raises(TypeError, match="unexpected keyword argument 'hint'"):  # not taken for from_kwargs' own
        activeperc_env.parallel_env(hint="red")


def test_autoreset_mode_given_to_one_room_says_where_it_goes():
    with pytest.raises(ValueError, match=r"vector_kwargs=\{'autoreset_mode': ...\}"):
        gymnasium.make_vec("activeperc/Joint-v1", 2, vectorization_mode="sync", autoreset_mode="SameStep")


def test_empty_room_is_allowed():
    assert EnvConfig(num_obstacles=0).num_obstacles == 0


def test_bad_render_mode_is_named():
    with pytest.raises(ValueError, match="ascii"):
        activeperc_env.env(render_mode="ascii")


def test_numpy_numbers_become_python_numbers():
    config = EnvConfig(width=np.int64(80), fov=np.float32(100), max_cycles=np.int32(12), pan_step=15)
    assert (config.width, config.fov, config.max_cycles, config.pan_step) == (80, 100.0, 12, 15.0)
    assert type(config.width) is int and type(config.fov) is float and type(config.pan_step) is float
    assert activeperc_env.Simulator(config, num_envs=np.int64(2)).num_envs == 2


def test_help_shows_every_field_with_its_default_and_meaning():
    from activeperc_rl.methods import METHOD_CLASSES
    from activeperc_rl.recipe import SECTIONS

    options = [cls.Options for cls in METHOD_CLASSES.values()]
    for cls in (EnvConfig, *SECTIONS.values(), *options):
        text = " ".join(pydoc.render_doc(cls, renderer=pydoc.plaintext).replace("|", " ").split())
        assert field_docs(cls).keys() == {f.name for f in dataclasses.fields(cls)}, cls
        for name, doc in field_docs(cls).items():
            assert f"{name} (" in text and f"default {getattr(cls(), name)!r}" in text, name
            assert doc in text, name
    assert "Horizontal field of view of the robot's camera" in EnvConfig.__doc__


def test_a_run_saved_before_room_v1_existed_is_a_v0_run(tmp_path):
    """config.yaml and checkpoints of earlier releases hold no env.version: they trained in v0, and load so."""

    import yaml

    from activeperc_rl.recipe import TrainConfig
    from activeperc_rl.runtime.checkpoint import load_run_config

    old = TrainConfig.from_options(env=EnvConfig(version=0)).to_dict()
    del old["env"]["version"]
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(old))
    assert load_run_config(tmp_path).env == EnvConfig(version=0)
    assert TrainConfig.from_dict({"env": {"fov": 100}}).env.version == DEFAULT  # a preset's room is today's default
    sim = activeperc_env.Simulator(EnvConfig(version=0))
    sim.reset(seeds=[0])
    state = sim.get_state()
    del state["config"]["version"]
    sim.set_state(state)  # a v0 simulator takes the old state
    with pytest.raises(ValueError, match="another config"):
        activeperc_env.Simulator(EnvConfig()).set_state(state)
    pickled = sim.__getstate__()
    del pickled["config"]["version"]
    copy = activeperc_env.Simulator.__new__(activeperc_env.Simulator)
    copy.__setstate__(pickled)  # an old pickle unpickles into a v0 room
    assert copy.config == EnvConfig(version=0) and dataclasses.asdict(copy.config) == dataclasses.asdict(sim.config)


def test_replacing_the_version_brings_that_versions_defaults():
    from activeperc_rl.recipe import TrainConfig

    v0 = TrainConfig().replace(version=0)
    assert v0.env == EnvConfig(version=0)
    kept = TrainConfig().replace(version=0, turn_speed=45)  # an option given with it stays as given
    assert kept.env == EnvConfig(version=0, turn_speed=45)
    changed = TrainConfig.from_options(env=EnvConfig(version=0, max_cycles=50)).replace(version=1).env
    assert changed == EnvConfig(max_cycles=50, version=1)
