"""Names of the scene's bodies, joints, actuators and cameras, and the robot's dimensions.

Every lookup of a MuJoCo element goes through these constants; the XML in ``assets/`` is the
other half of the contract.
"""

from pathlib import Path

ASSETS = Path(__file__).parent / "assets"

BASE_BODY = "base"
# the wheeled base (robot.WheeledBase): a free joint on two driven wheels
ROOT_JOINT = "root"
LEFT_WHEEL = "left_wheel"
RIGHT_WHEEL = "right_wheel"
# the planar bases (robot.PlanarBase, HolonomicBase): slides along x and y and a yaw hinge, each driven by a
# velocity servo of the same name with "drive_"
BASE_JOINTS = ("base_x", "base_y", "base_yaw")
BASE_DRIVES = ("drive_x", "drive_y", "drive_yaw")
PAN_JOINT = "pan"
PAN_ACTUATOR = "pan"
EYE_CAMERA = "eye"
MAP_CAMERA = "map"
GOAL_BODY = "goal"
OCCLUDER_BODIES = tuple(f"occluder_{i}" for i in range(6))

# geom group holding the robot's own visuals: hidden in its first-person view
ROBOT_GROUP = 2
# geom group that no view draws (MuJoCo shows groups 0-2 by default): the occluders a config leaves parked
HIDDEN_GROUP = 5

# values that must agree with the XML
WHEEL_RADIUS = 0.05
WHEEL_TRACK = 0.26  # distance between the wheels' contact points
ROBOT_RADIUS = 0.18  # a circle around the chassis, for layout and success checks
ROOM_HALF_X = 3.0  # inner half-length of the room (x)
ROOM_HALF_Y = 2.0  # inner half-width of the room (y)
GOAL_HALF = 0.2
OCCLUDER_HALF = (0.3, 0.3, 0.4)
PARK_X = 50.0  # unused occluders stand at x >= PARK_X, outside the walls
