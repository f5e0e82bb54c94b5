"""Room v3, the default: v1's robot and room, but the base slides and never turns, so only the camera sees to the
side."""

from activeperc_env.names import ASSETS
from activeperc_env.robot import HolonomicBase
from activeperc_env.rooms.record import Room

ROOM = Room(
    version=3,
    released="2026-12-03",
    scene=ASSETS / "scene_v1.xml",
    physics_timestep=0.02,
    base=HolonomicBase,
    mover_actions=("slide_left", "slide_right", "forward"),
    shuffle_occluders=True,
    defaults={"heading_spread": 90.0, "goal_distance": 4.0, "max_cycles": 90, "turn_speed": 30.0, "range_rays": 13},
    summary="a room in which the body cannot look: v1's robot and room whose base slides left, right or forward and "
    "never turns, so only the camera sees to the side; occluders in random places.",
    changes="""The three moves slide the base left, right or forward (`slide_left`, `slide_right`, `forward`, each at
`forward_speed`; `turn_speed` is unused), keeping the heading it started with, within 90 degrees of the goal's
bearing. The occluders trade places at random as in v2. Layouts, physics steps, sensors, reward and spaces are v1's.
Why: in v1 and v2 a learned mover found the goal by turning its body, which it must do anyway to face the goal, so no
looker lifted it ([results](results.md#room-v3)); here the scripted scan looker lifts the learned mover from 0.37
to 0.75, and a looker trained by `meta` lifts it too. The default room since 2026-12-05 (before: v1).""",
)
