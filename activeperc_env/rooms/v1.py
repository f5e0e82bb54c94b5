"""Room v1: a room in which looking pays, with a unicycle base that turns slowly and a range sensor."""

from activeperc_env.names import ASSETS
from activeperc_env.robot import PlanarBase
from activeperc_env.rooms.record import Room

ROOM = Room(
    version=1,
    released="2026-12-01",
    scene=ASSETS / "scene_v1.xml",
    physics_timestep=0.02,
    base=PlanarBase,
    mover_actions=("turn_left", "turn_right", "forward"),
    shuffle_occluders=False,
    defaults={"heading_spread": 90.0, "goal_distance": 4.0, "max_cycles": 90, "turn_speed": 30.0, "range_rays": 13},
    summary="a room in which looking pays: a unicycle base that turns a fifth as fast as the camera pans, a range "
    "sensor in the observation (`range`), the start and the goal 4 m apart, 90 cycles.",
    changes="""What changed from v0 ([design notes](design.md#room-v1-looking-pays-for-scripted-policies)):

- the robot (`assets/robot_v1.xml`): a heavy base driven as a unicycle by velocity servos on two slides and a yaw
  hinge, touching the room only with a frictionless bumper (nothing touches the floor), turning at 30 degrees a
  second (v0: 90) while the camera pans 30 degrees a look; physics in 10 steps of 20 ms a cycle (v0: 40 of 5 ms);
- a range sensor in the observation (`range`, 13 rays from -90 to +90 degrees, up to 2 m; it does not see the goal);
- the start and the goal 4 m apart (v0: 3), episodes of 90 cycles (v0: 150);
- `version`, `range_rays` and `range_max` are new options; the room, its boxes, the reward, the cycle and the spaces
  of the actions are v0's.""",
)
