"""Room v0: the paper-faithful room of the Figure 1 pilot, a robot on two driven wheels that sees only its camera."""

from activeperc_env.names import ASSETS
from activeperc_env.robot import WheeledBase
from activeperc_env.rooms.record import Room

ROOM = Room(
    version=0,
    released="2026-11-22",
    scene=ASSETS / "scene.xml",
    physics_timestep=0.005,
    base=WheeledBase,
    mover_actions=("turn_left", "turn_right", "forward"),
    shuffle_occluders=False,
    defaults={"heading_spread": 90.0, "goal_distance": 3.0, "max_cycles": 150, "turn_speed": 90.0, "range_rays": 0},
    summary="first release, the paper-faithful room of the Figure 1 pilot: a robot on two driven wheels that "
    "turns at 90 degrees a second, seeing only through its camera; 40 physics steps of 5 ms a cycle.",
    changes="""Kept with exactly its old trajectories (`tests/test_golden.py`). A `control_hz` whose period is not a
whole number of 5 ms physics steps is refused since 2026-11-24 (it used to be rounded to the nearest number of
steps: 30 Hz drove the wheels for 35 ms, 150 Hz for 5 ms); every value still accepted behaves as before, so v0 stays
v0. Since 2026-11-24 the envs can be copied and pickled, and `raw_env` no longer claims PettingZoo's
`is_parallelizable` (`aec_to_parallel(raw_env())` gave a game where the looker acted on the view before its own last
look); the game itself is unchanged. Since 2026-11-24 the bird's-eye map shows 4.8 m of the room's height instead of
4.6 (its camera cut off the outer 3 cm of the east and west walls); observations are unchanged.""",
)
