"""The message table: every request type, its fields and their kinds, and the checks run on
every incoming message (:func:`validate`, :func:`check_reports`).

The table is data: ``docs/protocol.md`` describes it and the fuzz tests are generated from it.
"""
from __future__ import annotations

import math
from typing import Any

from robo_comp.errors import FieldError, MalformedError, UnknownTypeError, VersionError
from robo_comp.protocol.wire import (
    PROTOCOL_VERSION,
    Message,
    describe_type,
    is_finite,
    decode_envelope,
)

#: Messages that may open a session on a connection that has none (a host may register first).
OPENING = frozenset({"hello", "register"})
#: Largest team radio payload, in bytes once packed.
MAX_RADIO = 4096
#: Radio messages per robot per second (token bucket, burst of the same size).
RADIO_RATE = 20.0

_INT = "int"
_NUM = "number"
_STR = "str"
_BOOL = "bool"
_LIST = "list"
_MAP = "map"
_BIN = "bytes"
_ANY = "any"
_OPT_INT = "int or nil"

# Field descriptions: type name -> {field: (kind, required)}.
REQUESTS: dict[str, dict[str, tuple[str, bool]]] = {
    # sessions (consoles, walls, scripts)
    "hello": {"token": (_STR, True), "client": (_STR, False), "instance": (_STR, False)},
    "heartbeat": {},
    "bye": {},
    "watch": {"on": (_BOOL, False)},
    "robots": {},
    "monitor": {"tag": (_INT, True)},
    "tasks": {"tag": (_INT, True)},
    "give": {"tag": (_INT, True), "task": (_STR, True), "args": (_LIST, False), "queue": (_BOOL, False)},
    "stop": {"tag": (_INT, True)},
    "snapshot": {},
    "arena": {},
    "stats": {},
    # the organiser's robot hosts as the referee sees them, and handing robots from one host to the next
    "hosts": {},
    "handover": {"tags": (_LIST, True)},
    # the match (referee: match, penalty, disqualify, broadcast)
    "match": {"action": (_STR, True), "seconds": (_NUM, False), "rule": (_STR, False)},
    "score": {},
    "penalty": {"team": (_STR, True), "points": (_NUM, True), "reason": (_STR, True)},
    "disqualify": {"tag": (_OPT_INT, False), "team": (_STR, False), "reason": (_STR, False)},
    "broadcast": {"message": (_STR, True)},
    "find": {"tag": (_INT, True), "x": (_NUM, True), "y": (_NUM, True), "kind": (_STR, False),
             "evidence": (_LIST, False)},
    "picture.get": {"id": (_INT, True)},
    "video.get": {"id": (_INT, True)},
    "map": {"tag": (_OPT_INT, False), "radius": (_INT, False)},
    "map.delta": {"since": (_INT, True)},
    # a team's teamwork settings: 'reallocate' moves a lost robot's tasks to teammates (the referee
    # names the 'team'); without 'reallocate' the reply says the setting
    "teamwork": {"reallocate": (_BOOL, False), "team": (_STR, False)},
    # team code (see robo_comp/core/uploads.py)
    "upload": {"tags": (_LIST, True), "filename": (_STR, True), "source": (_ANY, True), "kind": (_STR, False),
               "run": (_BOOL, False)},
    "unload": {"tags": (_LIST, True), "name": (_STR, True)},
    "extensions": {"tag": (_INT, True)},
    "approve": {"upload_id": (_INT, True), "ok": (_BOOL, False)},
    "sandbox.reset": {"tags": (_LIST, True)},
    # robot hosts
    "register": {
        "token": (_STR, True), "robot_id": (_STR, True), "tasks": (_LIST, False),
        "x": (_NUM, False), "y": (_NUM, False), "heading": (_NUM, False),
        "task_id": (_OPT_INT, False), "speed": (_NUM, False),
        # a task.done the core has not acknowledged (sent again after a reconnect), and whether
        # the robot registers for the first time since its host started
        "done": (_MAP, False), "fresh": (_BOOL, False),
    },
    "report": {
        "tag": (_INT, True), "x": (_NUM, True), "y": (_NUM, True), "heading": (_NUM, True),
        "moving": (_BOOL, False), "sensors": (_MAP, False),
    },
    # many robots of one host in one message: lists of the same length, row i is one report
    "reports": {
        "tags": (_LIST, True), "x": (_LIST, True), "y": (_LIST, True), "heading": (_LIST, True),
        "moving": (_LIST, False), "sensors": (_LIST, False), "sigma": (_LIST, False),
    },
    "task.next": {"tag": (_INT, True)},
    "task.done": {
        "tag": (_INT, True), "task_id": (_INT, True), "ok": (_BOOL, True),
        "status": (_STR, True), "result": (_ANY, False),
    },
    "radio": {"tag": (_INT, True), "to": (_OPT_INT, False), "data": (_ANY, True)},
    "leave": {"tag": (_INT, True)},
    # x/y/heading of a picture or a bump are the host's word only: the core judges at its tracked pose
    "picture": {"tag": (_INT, True), "x": (_NUM, False), "y": (_NUM, False), "heading": (_NUM, False),
                "png": (_BIN, True), "label": (_STR, False)},
    "bump": {"tag": (_INT, True), "x": (_NUM, False), "y": (_NUM, False), "with": (_OPT_INT, False)},
    # a short video of the robot's camera (WebM): examineArea films its turn on the spot
    "video": {"tag": (_INT, True), "x": (_NUM, False), "y": (_NUM, False), "heading": (_NUM, False),
              "webm": (_BIN, True), "seconds": (_NUM, False), "frames": (_INT, False), "label": (_STR, False)},
    # a cell a robot's sensors saw blocked that the map shows free (its team's map gets it)
    "obstacle": {"tag": (_INT, True), "x": (_INT, True), "y": (_INT, True)},
    "advertise": {"tag": (_INT, True), "tasks": (_LIST, True)},
    "log": {"tag": (_OPT_INT, False), "stream": (_STR, True), "text": (_STR, True)},
    # debug drawing of team code (robo_comp/protocol/drawing.py): one frame per robot, for its team only
    "draw": {"tags": (_LIST, True), "frames": (_LIST, True)},
    # replies from a robot host to a core-initiated request (stop, upload, unload, extensions)
    "reply": {},
}

#: Types a sender may use without a reply on success.
NOTIFICATIONS = frozenset({"report", "reports", "heartbeat", "bump", "log", "draw"})
#: Robots in one ``reports`` message at most.
MAX_REPORTS = 1000

#: Messages the core sends to robot hosts (requests expect a ``reply``) and their fields: a host
#: checks every one it gets against this table (:func:`validate_to_host`), as the core checks
#: every request against :data:`REQUESTS`.
TO_HOST: dict[str, dict[str, tuple[str, bool]]] = {
    "heartbeat": {"t": (_NUM, False), "core_id": (_STR, False)},
    "task.start": {"tag": (_INT, True), "task_id": (_INT, True), "name": (_STR, True), "args": (_LIST, True)},
    "task.interrupt": {"tag": (_INT, True), "task_id": (_INT, True), "name": (_STR, True), "args": (_LIST, True)},
    "stop": {"tag": (_INT, True)},
    "radio": {"tag": (_INT, True), "from": (_INT, True), "to": (_OPT_INT, False), "data": (_ANY, True)},
    "hold": {"on": (_BOOL, True), "phase": (_STR, False)},
    "map.delta": {"version": (_INT, True)},
    "event": {"topic": (_STR, True), "data": (_MAP, True)},
    "upload": {"tags": (_LIST, True), "filename": (_STR, True), "source": (_ANY, True)},
    "unload": {"tags": (_LIST, True), "name": (_STR, True)},
    "extensions": {"tags": (_LIST, True)},
    "sandbox.reset": {"tags": (_LIST, True)},
    "release": {"tag": (_INT, True), "message": (_STR, False)},
    "reply": {},
}
#: Their type names.
CORE_TO_HOST = tuple(t for t in TO_HOST if t != "reply")

#: Messages only the organiser's robot hosts send (``STATE/hosts/<team>.token``): they say what
#: happens in the world (robots, poses, pictures, bumps, task results) and answer for robots.
HOST_ONLY = frozenset({"register", "report", "reports", "task.next", "task.done", "radio", "leave",
                       "picture", "video", "bump", "obstacle", "advertise", "log", "draw", "reply"})
#: Messages every principal may send (a host reports a find for its team's code, reads the map).
ANY_ROLE = frozenset({"hello", "heartbeat", "bye", "arena", "map", "map.delta", "find"})
#: Messages of consoles, walls and scripts: a team's or the referee's token.
CONSOLE_ONLY = frozenset(REQUESTS) - HOST_ONLY - ANY_ROLE
#: What each role may send: the core refuses any other type from a session of that role
#: (``E_FORBIDDEN``). A team gives commands and reads its robots; only the organiser's hosts
#: speak for the world.
ROLE_MESSAGES: dict[str, frozenset[str]] = {
    "team": CONSOLE_ONLY | ANY_ROLE,
    "referee": CONSOLE_ONLY | ANY_ROLE,
    "host": HOST_ONLY | ANY_ROLE,
}

_NONE = type(None)
#: The Python types each field kind admits (None = anything). bool is not an int here.
_ALLOWED: dict[str, tuple[type, ...] | None] = {
    _ANY: None, _INT: (int,), _OPT_INT: (int, _NONE), _NUM: (int, float), _STR: (str,),
    _BOOL: (bool,), _LIST: (list,), _MAP: (dict,), _BIN: (bytes,),
}
Rows = list[tuple[str, tuple[type, ...] | None, bool, str]]


def _rows(table: dict[str, dict[str, tuple[str, bool]]]) -> dict[str, Rows]:
    """Per type: (field, allowed types, required, kind) rows, built once."""
    return {t: [(name, _ALLOWED[kind], req, kind) for name, (kind, req) in spec.items()] for t, spec in table.items()}


_CHECKS = _rows(REQUESTS)
_HOST_CHECKS = _rows(TO_HOST)


def check_reports(body: dict[str, Any]) -> int:
    """Check a validated ``reports`` body row by row; return the number of rows.

    Every list has one entry per robot: ``tags`` integers, ``x``/``y``/``heading`` finite
    numbers, ``moving`` true/false, ``sensors`` a map or nil. Raises :class:`FieldError`
    naming the first bad row.
    """
    tags = body["tags"]
    n = len(tags)
    if n > MAX_REPORTS:
        raise FieldError(f"'reports' holds {n} robots; the limit is {MAX_REPORTS} per message")
    for name in ("x", "y", "heading", "moving", "sensors", "sigma"):
        if name in body and len(body[name]) != n:
            raise FieldError(f"'reports' needs one {name!r} per tag: {n} tags, {len(body[name])} {name!r}")
    if _rows_fine(body):  # the common case, checked in C loops
        return n
    for i, tag in enumerate(tags):
        if type(tag) is not int:
            raise FieldError(f"'tags'[{i}] of 'reports' must be an integer, got {describe_type(tag)}")
    for name in ("x", "y", "heading", "sigma"):
        for i, v in enumerate(body.get(name, ())):
            if type(v) not in (int, float) or not is_finite(v) or (name == "sigma" and v < 0):
                raise FieldError(f"{name!r}[{i}] of 'reports' must be a finite number"
                                 f"{' of 0 or more' if name == 'sigma' else ''}, got {v!r}")
    for i, v in enumerate(body.get("moving", ())):
        if type(v) is not bool:
            raise FieldError(f"'moving'[{i}] of 'reports' must be true/false, got {describe_type(v)}")
    for i, v in enumerate(body.get("sensors", ())):
        if v is not None and type(v) is not dict:
            raise FieldError(f"'sensors'[{i}] of 'reports' must be a map or nil, got {describe_type(v)}")
    return n


_NUMBER_TYPES = frozenset({int, float})


def _rows_fine(body: dict[str, Any]) -> bool:
    """Whether every row of a ``reports`` body is well formed (no message: see check_reports)."""
    try:
        if not {int}.issuperset(map(type, body["tags"])):
            return False
        for name in ("x", "y", "heading", "sigma"):
            col = body.get(name, ())
            if not _NUMBER_TYPES.issuperset(map(type, col)) or not all(map(math.isfinite, col)):
                return False
        if "sigma" in body and min(body["sigma"], default=0) < 0:
            return False
    except OverflowError:  # an integer too large for a float: the slow path names it
        return False
    if not {bool}.issuperset(map(type, body.get("moving", ()))):
        return False
    return {dict, _NONE}.issuperset(map(type, body.get("sensors", ())))


def decode(frame: bytes) -> Message:
    """Decode and validate one incoming frame into a :class:`Message`.

    Raises :class:`RoboCompError` subclasses with a sentence a student understands; the
    caller replies with the error and goes on serving.
    """
    raw, id_ = decode_envelope(frame)
    return validate(raw, id_)


def validate(raw: dict[str, Any], id_: int) -> Message:
    """Validate a decoded map (version, type, id, body fields)."""
    v = raw.get("v")
    if v != PROTOCOL_VERSION:
        if type(v) is int and 0 < v < PROTOCOL_VERSION:
            raise VersionError(
                f"your program speaks protocol version {v}, and this core speaks version {PROTOCOL_VERSION} "
                "(sessions are proved with a secret on every message since version 2): update robo_comp "
                "on this machine (pip install -U robo_comp, or git pull in the team template) and start "
                "the program again")
        raise VersionError(
            f"protocol version {v!r} is not spoken here; this core speaks version {PROTOCOL_VERSION}")
    type_ = raw.get("type")
    if type(type_) is not str:
        raise MalformedError("message needs a 'type' string")
    if type(raw.get("id")) is not int:
        raise MalformedError("message needs an integer request 'id'")
    spec = REQUESTS.get(type_)
    if spec is None:
        raise UnknownTypeError(f"unknown message type {type_!r}; see docs/protocol.md for the types")
    if type_ == "reply":
        return Message(type_, id_, raw)
    body = raw.get("body", {})
    if type(body) is dict and _FITS[type_](body):  # the common case: every field as the table says
        return Message(type_, id_, body)
    _check_body(type_, body, _CHECKS[type_])
    return Message(type_, id_, body)


def _check_body(type_: str, body: Any, rows: Rows) -> None:
    """Raise :class:`FieldError` naming the first field of ``body`` the rows do not admit."""
    if type(body) is not dict:
        raise FieldError(f"'body' of {type_!r} must be a map, got {describe_type(body)}")
    for name, allowed, required, kind in rows:
        if name not in body:
            if required:
                raise FieldError(f"{type_!r} needs the field {name!r} ({kind})")
        elif allowed is not None and type(body[name]) not in allowed:
            raise FieldError(
                f"field {name!r} of {type_!r} must be {kind}, got {describe_type(body[name])}")
        elif kind == _NUM and not is_finite(body[name]):
            raise FieldError(f"field {name!r} of {type_!r} must be a finite number, got {body[name]!r}")


def validate_to_host(raw: Any) -> Message:
    """Check a decoded message from the core on a robot host (:data:`TO_HOST`): a type the table
    names, an integer id, the fields it needs of the kinds it says. Raises the error that names what
    is wrong; a host logs it and ignores the message (a reply is checked by its own decoder)."""
    if type(raw) is not dict:
        raise MalformedError(f"a message from the core must be a map, got {describe_type(raw)}")
    type_ = raw.get("type")
    if type(type_) is not str or type_ not in TO_HOST:
        raise UnknownTypeError(f"the core sent a message of type {type_!r}, which robot hosts do not take")
    id_ = raw.get("id", 0)
    if type(id_) is not int:
        raise MalformedError("a message from the core needs an integer 'id'")
    if type_ == "reply":
        return Message(type_, id_, raw)
    body = raw.get("body", {})
    _check_body(type_, body, _HOST_CHECKS[type_])
    return Message(type_, id_, body)



# Per type, a check of the body generated from the table: straight-line code, one test per field,
# that says only whether the body fits (True for almost every message); when it does not, the
# loop in validate() runs and names the first field that is wrong. The table stays the one source.
_TESTS = {
    _INT: "type(v) is int", _OPT_INT: "(type(v) is int or v is None)", _STR: "type(v) is str",
    _BOOL: "type(v) is bool", _LIST: "type(v) is list", _MAP: "type(v) is dict", _BIN: "type(v) is bytes",
    _NUM: "(type(v) is int or (type(v) is float and v - v == 0.0))",  # inf - inf and nan - nan are nan
}
_MISSING = object()


def _compile_fit(type_: str, fields: dict[str, tuple[str, bool]]) -> Any:
    lines = ["def fits(body):"]
    for name, (kind, required) in fields.items():
        if kind == _ANY:
            if required:
                lines.append(f"    if {name!r} not in body: return False")
            continue
        lines.append(f"    v = body.get({name!r}, _MISSING)")
        if required:
            lines.append(f"    if v is _MISSING or not {_TESTS[kind]}: return False")
        else:
            lines.append(f"    if v is not _MISSING and not {_TESTS[kind]}: return False")
    lines.append("    return True")
    scope: dict[str, Any] = {"_MISSING": _MISSING}
    exec(compile("\n".join(lines), f"<protocol check of {type_!r}>", "exec"), scope)
    return scope["fits"]


_FITS = {t: _compile_fit(t, spec) for t, spec in REQUESTS.items()}
