"""Robot models: built-in Universal Robots arms and URDF loading.

>>> from sklearn_gpcd.robots import load_robot
>>> load_robot("ur10").n_joints
6
"""

from .loading import list_robots, load_robot, resolve_robot
from .robot import Robot
from .ur_parameters import UR_PARAMETERS

__all__ = ["Robot", "load_robot", "list_robots", "resolve_robot", "UR_PARAMETERS"]
