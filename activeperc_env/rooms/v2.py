"""Room v2: room v1 without its hints of where the goal lies."""

from activeperc_env.names import ASSETS
from activeperc_env.robot import PlanarBase
from activeperc_env.rooms.record import Room

ROOM = Room(
    version=2,
    released="2026-12-03",
    scene=ASSETS / "scene_v1.xml",
    physics_timestep=0.02,
    base=PlanarBase,
    mover_actions=("turn_left", "turn_right", "forward"),
    shuffle_occluders=True,
    defaults={"heading_spread": 180.0, "goal_distance": 4.0, "max_cycles": 90, "turn_speed": 30.0, "range_rays": 13},
    summary="room v1 without hints of where the goal lies: any start heading, occluders in random places.",
    changes="""A camera held forward no longer finds the goal by itself. The robot starts facing any way at all
(`heading_spread` 180: in v1 the goal lay within 90 degrees of ahead, so driving ahead was the right guess), and the
occluders trade places at random once placed (in v1 the green box always stood on the line from the start to the
goal). The robot, physics, sensors, reward and spaces are v1's. What it does to learning is in
[the design notes](design.md#room-v2-no-hints).""",
)
