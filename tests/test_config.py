"""Invalid configuration values are refused with a message that names them."""

import pytest

import activeperc_env
from activeperc_env.config import EnvConfig


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
        ("pan_range", 190),
        ("pan_step", 0),
        ("control_hz", 0),
        ("looker_reward", "mine"),
    ],
)
def test_invalid_value_names_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        EnvConfig(**{field: value})


def test_unknown_option_is_named():
    with pytest.raises(ValueError, match="colour"):
        activeperc_env.parallel_env(colour="red")


def test_empty_room_is_allowed():
    assert EnvConfig(num_obstacles=0).num_obstacles == 0


def test_bad_render_mode_is_named():
    with pytest.raises(ValueError, match="ascii"):
        activeperc_env.env(render_mode="ascii")
