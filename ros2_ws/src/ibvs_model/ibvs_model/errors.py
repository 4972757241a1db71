"""
Typed exceptions raised by the model on bad input.

Every exception derives from :class:`ModelError`, itself a :class:`ValueError`, so a
caller that wants to reject any bad input catches one class, while a caller that cares
about the reason (an unreachable pose is not a malformed array) catches the subclass.
"""


class ModelError(ValueError):
    """Base class of every error raised by :mod:`ibvs_model`."""


class InvalidInputError(ModelError):
    """An argument has the wrong shape, is not finite, or is not a valid rotation."""


class UnreachablePoseError(ModelError):
    """No inverse-kinematics branch reaches the pose within the joint limits."""


class BehindCameraError(ModelError):
    """A point lies on or behind the camera's image plane (Z^C <= 0)."""


class TriangulationError(ModelError):
    """Stereo coordinates cannot be triangulated (disparity not positive, v mismatch)."""
