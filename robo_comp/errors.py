"""The one exception hierarchy of robo_comp; every error maps to a stable protocol code.

A ``RoboCompError`` raised anywhere while the core handles a request becomes an error
reply ``{"code": err.code, "message": str(err)}``; clients turn error replies back into
the matching exception class with :func:`error_from_code`.
"""
from __future__ import annotations


class RoboCompError(Exception):
    """Base of every error robo_comp reports; ``code`` is the stable protocol code."""

    code = "E_INTERNAL"

    def __init__(self, message: str, **details: object) -> None:
        super().__init__(message)
        self.message = message
        self.details = details


class MalformedError(RoboCompError):
    """The frame is not a msgpack map of the protocol's shape."""

    code = "E_MALFORMED"


class VersionError(RoboCompError):
    """The frame names a protocol version the core does not speak."""

    code = "E_VERSION"


class UnknownTypeError(RoboCompError):
    """The frame's ``type`` names no request the core knows."""

    code = "E_UNKNOWN_TYPE"


class FieldError(RoboCompError):
    """A field is missing or of the wrong type or value."""

    code = "E_FIELD"


class TooLargeError(RoboCompError):
    """The frame or a payload in it exceeds a size limit."""

    code = "E_TOO_LARGE"


class AuthError(RoboCompError):
    """No valid token was presented (or the session is unknown)."""

    code = "E_AUTH"


class ForbiddenError(RoboCompError):
    """The caller's role may not do this (for example a team doing a referee action)."""

    code = "E_FORBIDDEN"


class NotYoursError(RoboCompError):
    """The robot exists, or may exist, but does not belong to the caller's team."""

    code = "E_NOT_YOURS"


class NoSuchRobotError(RoboCompError):
    """No robot has that tag."""

    code = "E_NO_ROBOT"


class BadTaskError(RoboCompError):
    """The task is unknown to the robot or its arguments do not fit its description."""

    code = "E_BAD_TASK"


class UnavailableError(RoboCompError):
    """The robot is lost or has left, so it cannot act now."""

    code = "E_UNAVAILABLE"


class RateLimitError(RoboCompError):
    """The sender exceeded a rate limit; try again later."""

    code = "E_RATE"


class TimeoutError_(RoboCompError):
    """Something did not answer in time (the core, or a robot through the core)."""

    code = "E_TIMEOUT"


class PhaseError(RoboCompError):
    """The match phase does not allow this command now."""

    code = "E_PHASE"


class ScenarioError(RoboCompError):
    """A scenario or map file is invalid; the message names the file, line and field."""

    code = "E_SCENARIO"


class UploadError(RoboCompError):
    """An uploaded module failed the checked init contract or a sandbox limit."""

    code = "E_UPLOAD"


class StorageError(RoboCompError):
    """The core cannot write its event log (disk full, I/O error): it refuses what would change the match."""

    code = "E_STORAGE"


class ConnectionLostError(RoboCompError):
    """The client lost its connection to the core (raised on the client side only)."""

    code = "E_CONNECTION"


class HeldError(RoboCompError):
    """A robot is held by another robot host that is still running it (the referee hands it over)."""

    code = "E_HELD"


class ImplausibleError(RoboCompError):
    """A claim about the world that the match cannot believe (a pose the robot could not reach)."""

    code = "E_IMPLAUSIBLE"


ALL_ERRORS: tuple[type[RoboCompError], ...] = (
    RoboCompError, MalformedError, VersionError, UnknownTypeError, FieldError, TooLargeError,
    AuthError, ForbiddenError, NotYoursError, NoSuchRobotError, BadTaskError, UnavailableError,
    RateLimitError, TimeoutError_, PhaseError, ScenarioError, UploadError, StorageError, ConnectionLostError,
    HeldError, ImplausibleError,
)
_BY_CODE = {cls.code: cls for cls in ALL_ERRORS}


def error_from_code(code: str, message: str, details: object = None) -> RoboCompError:
    """Build the exception that matches a protocol error ``code`` (base class if unknown);
    ``details`` (a map, e.g. an upload's file, line and rule) becomes ``err.details``."""
    cls = _BY_CODE.get(code, RoboCompError)
    err = cls(message, **(details if isinstance(details, dict) else {}))
    err.code = code
    return err
