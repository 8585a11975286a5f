"""Exceptions raised by pmaccuracy.

Every problem with the user's input or with a pose where the model is undefined
raises a subclass of :class:`PmAccuracyError`; the command-line interface turns
each into one line on stderr and exit status 2.
"""

from __future__ import annotations


class PmAccuracyError(Exception):
    """Base class of every error this package raises on purpose."""


class ConfigError(PmAccuracyError, ValueError):
    """A parameter file or value is malformed: names the file, the key and the problem."""

    def __init__(self, message: str, *, source: str | None = None, key: str | None = None):
        self.message = message
        self.source = source
        self.key = key
        where = ": ".join(part for part in (source, key) if part)
        super().__init__(f"{where}: {message}" if where else message)


class GeometryError(ConfigError):
    """The manipulator's parameters do not describe a usable 3-PPR (e.g. guide parallel to bearing)."""


class ClearanceError(ConfigError):
    """A clearance set is malformed (negative, non-finite or missing values)."""


class PoseError(PmAccuracyError, ValueError):
    """A pose cannot be used: outside the joint ranges, singular, or non-finite."""


class OutsideJointLimitsError(PoseError):
    """A pose needs joint values outside the actuated or passive ranges."""


class SingularPoseError(PoseError):
    """A pose lies at or near a parallel singularity (det A = 0, Eq. 3-5)."""


class NoSolutionError(PoseError):
    """Forward kinematics has no real assembly mode for the given actuator values."""


class CertificationError(PoseError):
    """No certified worst-case bound at a pose: the remainder of the exact loop closure cannot be bounded
    over the error set (errors too large, some configuration cannot be assembled, near a singularity)."""


class EmptyWorkspaceError(PoseError):
    """The constant-orientation workspace is empty for the requested orientation."""


class MeasurementFileError(ConfigError):
    """A measurement CSV file is malformed: names the row and the problem."""


class VisionError(PmAccuracyError, ValueError):
    """An image does not show the expected markers, or a calibration is unusable."""


class UnsupportedArchitectureError(ConfigError):
    """The requested computation is not available for this robot's architecture."""


class MissingDependencyError(PmAccuracyError, ImportError):
    """An optional dependency is not installed; the message names the extra that installs it."""
