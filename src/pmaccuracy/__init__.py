"""pmaccuracy: exact worst-case pose errors of planar parallel manipulators (any architecture) with joint clearances.

Implements and extends G. Wu, S. Bai, J. A. Kepler, S. Caro, "Error Modelling and
Experimental Validation of a Planar 3-PPR Parallel Manipulator with Joint
Clearances", ASME J. Mechanisms Robotics 4(4), 041011, 2012.

Units: lengths in mm and angles in radians in the API; files and the command
line use degrees (always in keys or options ending in ``deg``).
"""

from .errors import (ClearanceError, ConfigError, EmptyWorkspaceError, GeometryError, MeasurementFileError,
                     NoSolutionError, OutsideJointLimitsError, PmAccuracyError, PoseError, SingularPoseError,
                     VisionError)
from .geometry import Leg, Manipulator
from .kinematics import (FKSolution, IKSolution, forward_kinematics, inverse_kinematics, jacobians,
                         kinematic_jacobian, singularity)

__version__ = "0.1.0"

__all__ = [
    "ClearanceError", "ConfigError", "EmptyWorkspaceError", "FKSolution", "GeometryError", "IKSolution", "Leg",
    "Manipulator", "MeasurementFileError", "NoSolutionError", "OutsideJointLimitsError", "PmAccuracyError",
    "PoseError", "SingularPoseError", "VisionError", "forward_kinematics", "inverse_kinematics", "jacobians",
    "kinematic_jacobian", "singularity", "__version__",
]
