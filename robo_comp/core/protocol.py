"""The wire protocol: msgpack frames, versioned, with typed fields and stable error codes.

Every message is one msgpack map (one ZeroMQ frame after the ROUTER's identity frame)::

    {"v": 2, "type": "give", "id": 7, "s": "9f2c...", "body": {...}}   # request or notification
    {"v": 2, "type": "reply", "id": 7, "ok": True, "body": {...}}
    {"v": 2, "type": "reply", "id": 7, "ok": False, "error": {"code": "E_FIELD", "message": "..."}}

A session belongs to whoever proved it, never to a connection's routing id: ``hello`` (or a
host's first ``register``) is answered with a random ``session`` secret, and every later message
of that connection carries it as ``"s"``; a message without it gets ``E_AUTH`` and changes
nothing. Clients set a random routing id of :data:`ROUTING_ID_BYTES` bytes on every socket they
open (:func:`new_routing_id`).

Requests get exactly one reply. Notifications (``report``, ``heartbeat``) get a reply only
when they are rejected, so that a sender learns what was wrong. Events go out on the PUB
socket as two frames ``[topic, msgpack map]`` and to watching sessions as ``event`` messages.
See ``docs/protocol.md`` for every type and field.
"""
from __future__ import annotations

import math
import secrets
from dataclasses import dataclass, field
from typing import Any

import msgpack

from robo_comp.world.public import unpack_walls  # noqa: F401  (clients read arenas with it)
from robo_comp.errors import (
    FieldError,
    MalformedError,
    RoboCompError,
    TooLargeError,
    UnknownTypeError,
    VersionError,
)

PROTOCOL_VERSION = 2
#: The envelope key that carries a session's secret on every message after ``hello``.
SESSION_KEY = "s"
#: Bytes of a session secret (sent as hex text: twice as many characters).
SESSION_BYTES = 16
#: Length of the random routing id every client sets on its sockets (ZMQ_ROUTING_ID).
ROUTING_ID_BYTES = 16
#: Messages that may open a session on a connection that has none (a host may register first).
OPENING = frozenset({"hello", "register"})
#: Largest frame the core decodes; larger frames get an ``E_TOO_LARGE`` reply.
MAX_FRAME = 1 << 20
#: Hard cap set on the sockets (ZMQ_MAXMSGSIZE): peers sending more are disconnected by libzmq.
SOCKET_MAX_FRAME = 16 << 20
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
    "hello": {"token": (_STR, True), "client": (_STR, False)},
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
    # the match (referee: match, penalty, disqualify, broadcast)
    "match": {"action": (_STR, True), "seconds": (_NUM, False)},
    "score": {},
    "penalty": {"team": (_STR, True), "points": (_NUM, True), "reason": (_STR, True)},
    "disqualify": {"tag": (_OPT_INT, False), "team": (_STR, False), "reason": (_STR, False)},
    "broadcast": {"message": (_STR, True)},
    "find": {"tag": (_INT, True), "x": (_NUM, True), "y": (_NUM, True), "kind": (_STR, False),
             "evidence": (_LIST, False)},
    "picture.get": {"id": (_INT, True)},
    "map": {"tag": (_OPT_INT, False), "radius": (_INT, False)},
    "map.delta": {"since": (_INT, True)},
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
        "task_id": (_OPT_INT, False),
    },
    "report": {
        "tag": (_INT, True), "x": (_NUM, True), "y": (_NUM, True), "heading": (_NUM, True),
        "moving": (_BOOL, False), "sensors": (_MAP, False),
    },
    # many robots of one host in one message: lists of the same length, row i is one report
    "reports": {
        "tags": (_LIST, True), "x": (_LIST, True), "y": (_LIST, True), "heading": (_LIST, True),
        "moving": (_LIST, False), "sensors": (_LIST, False),
    },
    "task.next": {"tag": (_INT, True)},
    "task.done": {
        "tag": (_INT, True), "task_id": (_INT, True), "ok": (_BOOL, True),
        "status": (_STR, True), "result": (_ANY, False),
    },
    "radio": {"tag": (_INT, True), "to": (_OPT_INT, False), "data": (_ANY, True)},
    "leave": {"tag": (_INT, True)},
    "picture": {"tag": (_INT, True), "x": (_NUM, True), "y": (_NUM, True), "heading": (_NUM, True),
                "png": (_BIN, True), "label": (_STR, False)},
    "bump": {"tag": (_INT, True), "x": (_NUM, True), "y": (_NUM, True), "with": (_OPT_INT, False)},
    "advertise": {"tag": (_INT, True), "tasks": (_LIST, True)},
    "log": {"tag": (_OPT_INT, False), "stream": (_STR, True), "text": (_STR, True)},
    # replies from a robot host to a core-initiated request (stop, upload, unload, extensions)
    "reply": {},
}

#: Types a sender may use without a reply on success.
NOTIFICATIONS = frozenset({"report", "reports", "heartbeat", "bump", "log"})
#: Robots in one ``reports`` message at most.
MAX_REPORTS = 1000

#: Messages the core sends to robot hosts (requests expect a ``reply``).
CORE_TO_HOST = ("heartbeat", "task.start", "task.interrupt", "stop", "radio", "hold", "map.delta", "event",
                "upload", "unload", "extensions", "sandbox.reset")

#: Keys left out of the PUB (public) view of an event: they stay with the owner and referee.
PRIVATE_KEYS = frozenset({"status", "result", "data", "args", "message", "cancelled", "code", "robot_id",
                          "tasks", "evidence"})
#: The ``team`` of an event meant for every watching session (a broadcast).
EVERYONE = "*"

#: Event topics; the PUB socket uses them as the first frame.
TOPICS = (
    "robot.registered", "robot.positions", "robot.lost", "robot.returned", "robot.left",
    "task.given", "task.started", "task.done", "robot.stopped", "radio", "refused", "core.started", "core.recovered", "core.storage",
    "match.phase", "score", "score.change", "penalty", "disqualified", "broadcast", "find.reported",
    "picture", "robot.bump", "robot.tasks", "robot.log", "upload.pending", "upload.sent", "upload.done",
    "upload.unloaded", "sandbox.reset",
)


@dataclass(slots=True)
class Message:
    """A decoded, validated protocol message."""

    type: str
    id: int
    body: dict[str, Any] = field(default_factory=dict)


def pack(obj: Any) -> bytes:
    """Encode one frame."""
    return msgpack.packb(obj, use_bin_type=True)


def unpack(frame: bytes) -> Any:
    """Decode one frame without validation (clients reading the core's messages)."""
    return msgpack.unpackb(frame, raw=False)


def request(type_: str, id_: int, body: dict[str, Any] | None = None, session: str | None = None) -> bytes:
    """Encode a request or notification frame; ``session`` is the secret the core gave this
    connection at ``hello`` (every message after it must carry it)."""
    if session is None:
        return pack({"v": PROTOCOL_VERSION, "type": type_, "id": id_, "body": body or {}})
    return pack({"v": PROTOCOL_VERSION, "type": type_, "id": id_, SESSION_KEY: session, "body": body or {}})


def new_session_secret() -> str:
    """A fresh, unguessable session secret (hex text)."""
    return secrets.token_hex(SESSION_BYTES)


def new_routing_id() -> bytes:
    """A random routing id for a client socket: :data:`ROUTING_ID_BYTES` bytes, the first never
    zero (libzmq keeps ids that start with a zero byte for the ones it makes up itself).

    A fresh id for every socket means that a reconnecting client never competes with its own old,
    half-dead connection for one id, and that nobody can guess the id of another's connection."""
    rid = bytearray(secrets.token_bytes(ROUTING_ID_BYTES))
    rid[0] = rid[0] | 0x80
    return bytes(rid)


def ok_reply(id_: int, body: dict[str, Any] | None = None, session: str | None = None) -> bytes:
    """Encode a successful reply to request ``id_`` (a robot host answering the core passes its
    ``session`` secret: to the core, a reply is a message like any other)."""
    msg = {"v": PROTOCOL_VERSION, "type": "reply", "id": id_, "ok": True, "body": body or {}}
    if session is not None:
        msg[SESSION_KEY] = session
    return pack(msg)


def error_reply(id_: int, err: RoboCompError, session: str | None = None) -> bytes:
    """Encode an error reply carrying the error's stable code and its sentence."""
    error: dict[str, Any] = {"code": err.code, "message": err.message}
    if err.details:  # e.g. an upload's file, line and rule
        error["details"] = err.details
    msg = {"v": PROTOCOL_VERSION, "type": "reply", "id": id_, "ok": False, "error": error}
    if session is not None:
        msg[SESSION_KEY] = session
    return pack(msg)


def event_frames(topic: str, payload: dict[str, Any]) -> list[bytes]:
    """Encode an event for the PUB socket: ``[topic, payload]``."""
    return [topic.encode(), pack(payload)]


_NONE = type(None)


def _finite(value: Any) -> bool:
    return type(value) is not float or math.isfinite(value)
#: The Python types each field kind admits (None = anything). bool is not an int here.
_ALLOWED: dict[str, tuple[type, ...] | None] = {
    _ANY: None, _INT: (int,), _OPT_INT: (int, _NONE), _NUM: (int, float), _STR: (str,),
    _BOOL: (bool,), _LIST: (list,), _MAP: (dict,), _BIN: (bytes,),
}
# Per type: (field, allowed types, required, kind) rows, built once.
_CHECKS: dict[str, list[tuple[str, tuple[type, ...] | None, bool, str]]] = {
    t: [(name, _ALLOWED[kind], req, kind) for name, (kind, req) in spec.items()]
    for t, spec in REQUESTS.items()
}


_TYPE_NAMES = {int: "an integer", float: "a number", str: "a string", bool: "true/false",
               list: "a list", dict: "a map", bytes: "bytes", type(None): "nil"}


def _describe(value: Any) -> str:
    return _TYPE_NAMES.get(type(value), type(value).__name__)


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
    for name in ("x", "y", "heading", "moving", "sensors"):
        if name in body and len(body[name]) != n:
            raise FieldError(f"'reports' needs one {name!r} per tag: {n} tags, {len(body[name])} {name!r}")
    for i, tag in enumerate(tags):
        if type(tag) is not int:
            raise FieldError(f"'tags'[{i}] of 'reports' must be an integer, got {_describe(tag)}")
    for name in ("x", "y", "heading"):
        for i, v in enumerate(body[name]):
            if type(v) not in (int, float) or not _finite(v):
                raise FieldError(f"{name!r}[{i}] of 'reports' must be a finite number, got {v!r}")
    for i, v in enumerate(body.get("moving", ())):
        if type(v) is not bool:
            raise FieldError(f"'moving'[{i}] of 'reports' must be true/false, got {_describe(v)}")
    for i, v in enumerate(body.get("sensors", ())):
        if v is not None and type(v) is not dict:
            raise FieldError(f"'sensors'[{i}] of 'reports' must be a map or nil, got {_describe(v)}")
    return n


def decode_envelope(frame: bytes) -> tuple[dict[str, Any], int]:
    """Check size and msgpack shape; return the raw map and its request id (0 if unknown).

    Raises a :class:`RoboCompError` whose reply should go to request id 0 when the id
    cannot be read.
    """
    if len(frame) > MAX_FRAME:
        raise TooLargeError(
            f"message is {len(frame)} bytes; the limit is {MAX_FRAME} bytes (split or shrink it)")
    try:
        raw = msgpack.unpackb(frame, raw=False, strict_map_key=True)
    except Exception:
        raise MalformedError("message is not valid msgpack; send one msgpack map per frame") from None
    if type(raw) is not dict:
        raise MalformedError(f"message must be a msgpack map, got {_describe(raw)}")
    return raw, raw.get("id") if type(raw.get("id")) is int else 0


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
    if type(body) is not dict:
        raise FieldError(f"'body' of {type_!r} must be a map, got {_describe(body)}")
    for name, allowed, required, kind in _CHECKS[type_]:
        if name not in body:
            if required:
                raise FieldError(f"{type_!r} needs the field {name!r} ({kind})")
        elif allowed is not None and type(body[name]) not in allowed:
            raise FieldError(
                f"field {name!r} of {type_!r} must be {kind}, got {_describe(body[name])}")
        elif kind == _NUM and not _finite(body[name]):
            raise FieldError(f"field {name!r} of {type_!r} must be a finite number, got {body[name]!r}")
    return Message(type_, id_, body)

