"""The one reply decoder: every client turns the core's replies into a body or an exception here."""
from __future__ import annotations

from typing import Any

from robo_comp.errors import MalformedError, RoboCompError, error_from_code


def reply_error(msg: dict[str, Any]) -> RoboCompError | None:
    """The :class:`RoboCompError` an error reply stands for (the class matching its code, with the
    core's sentence and details), or None for an ok reply."""
    if msg.get("ok"):
        return None
    err = msg.get("error")
    if not isinstance(err, dict):
        return MalformedError("the core sent an error reply without an 'error' map")
    return error_from_code(str(err.get("code", "E_INTERNAL")), str(err.get("message", "unknown error")),
                           err.get("details"))


def reply_body(msg: dict[str, Any]) -> dict[str, Any]:
    """The body of an ok reply; raise the matching :class:`RoboCompError` for an error reply."""
    exc = reply_error(msg)
    if exc is not None:
        raise exc
    body = msg.get("body")
    return body if isinstance(body, dict) else {}
