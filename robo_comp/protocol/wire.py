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

from robo_comp.errors import MalformedError, RoboCompError, TooLargeError

PROTOCOL_VERSION = 2
#: The envelope key that carries a session's secret on every message after ``hello``.
SESSION_KEY = "s"
#: Bytes of a session secret (sent as hex text: twice as many characters).
SESSION_BYTES = 16
#: Length of the random routing id every client sets on its sockets (ZMQ_ROUTING_ID).
ROUTING_ID_BYTES = 16
#: Largest frame the core decodes; larger frames get an ``E_TOO_LARGE`` reply.
MAX_FRAME = 1 << 20
#: Hard cap set on the ROUTER (ZMQ_MAXMSGSIZE): a peer sending a larger frame, or a larger command
#: before its handshake is done, is disconnected by libzmq. Frames between :data:`MAX_FRAME` and
#: this size get an ``E_TOO_LARGE`` reply.
SOCKET_MAX_FRAME = MAX_FRAME + (64 << 10)

# Decoding is bounded before it starts: msgpack refuses these at once, so that no frame costs the
# core's loop more than a few milliseconds (see docs/security.md and bench/bench_transport.py).
#: Longest string and binary value in a frame (an upload's source, a picture's PNG).
MAX_STR = MAX_FRAME
#: Most entries in one array: a ``reports`` batch has :data:`~robo_comp.protocol.messages.MAX_REPORTS`
#: rows; a task's result (64 KiB packed) can hold at most this many one-byte values.
MAX_ARRAY = 1 << 16
#: Most keys in one map (sensor readings, a task's result).
MAX_MAP = 1 << 12
#: Frames up to this size are decoded without counting: even the slowest shape of this many bytes
#: (empty maps, each a new object) decodes in a few milliseconds.
SMALL_FRAME = 32 << 10
#: Work a larger frame may cost, in units: every map and array counts :data:`CONTAINER_COST` plus
#: one per entry (a new map or array costs about as much as ten numbers or short strings). A
#: 1,000-robot ``reports`` batch with a sensor map per robot costs about 30,000; a frame that would
#: cost more is refused as soon as it passes the limit (arrays are counted when they end).
MAX_OBJECTS = 100_000
#: What one map or array costs of :data:`MAX_OBJECTS`.
CONTAINER_COST = 10
#: Deepest nesting of maps and arrays: msgpack's decoder keeps its own stack of this size and
#: refuses deeper frames itself (at no cost: the stack is fixed).
MAX_DEPTH = 1024


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


#: Length bounds of a client's ``instance`` id (hello): random, so nobody ends a session by guessing it.
INSTANCE_MIN, INSTANCE_MAX = 16, 64


def new_instance_id() -> str:
    """A client's ``instance`` id for hello: random hex, kept across the client's reconnects."""
    return secrets.token_hex(INSTANCE_MIN)


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


def is_finite(value: Any) -> bool:
    """False for a float that is NaN or infinite (other values count as finite)."""
    return type(value) is not float or math.isfinite(value)


_TYPE_NAMES = {int: "an integer", float: "a number", str: "a string", bool: "true/false",
               list: "a list", dict: "a map", bytes: "bytes", type(None): "nil"}


def describe_type(value: Any) -> str:
    """A student's word for the type of ``value`` ("an integer", "a map", ...)."""
    return _TYPE_NAMES.get(type(value), type(value).__name__)


class _TooMany(Exception):
    """Raised inside msgpack's decoder when a frame makes more than :data:`MAX_OBJECTS` objects."""


class _Budget:
    """msgpack's ``object_hook``/``list_hook`` for one frame: counts each finished map or array
    (:data:`CONTAINER_COST` plus its entries) and stops the decoding once :data:`MAX_OBJECTS` are spent."""

    __slots__ = ("left",)

    def __init__(self) -> None:
        self.left = MAX_OBJECTS

    def __call__(self, obj: Any) -> Any:
        self.left -= CONTAINER_COST + len(obj)
        if self.left < 0:
            raise _TooMany
        return obj


#: Keyword arguments of every unpackb the core runs on a peer's frame.
_LIMITS: dict[str, Any] = dict(raw=False, strict_map_key=True, max_str_len=MAX_STR, max_bin_len=MAX_STR,
                               max_array_len=MAX_ARRAY, max_map_len=MAX_MAP, max_ext_len=0)


def decode_frame(frame: bytes) -> Any:
    """Decode one frame from a peer within the limits above (any msgpack value; no shape check).

    Raises :class:`TooLargeError` for a frame over a size, count or nesting limit and
    :class:`MalformedError` for one that is not msgpack.
    """
    if len(frame) > MAX_FRAME:
        raise TooLargeError(
            f"message is {len(frame)} bytes; the limit is {MAX_FRAME} bytes (split or shrink it)")
    try:
        if len(frame) <= SMALL_FRAME:
            raw = msgpack.unpackb(frame, **_LIMITS)
        else:
            budget = _Budget()
            raw = msgpack.unpackb(frame, object_hook=budget, list_hook=budget, **_LIMITS)
    except msgpack.StackError:
        raise TooLargeError(f"message nests maps and lists more than {MAX_DEPTH} deep; flatten it") from None
    except _TooMany:
        raise TooLargeError(
            f"message holds too many maps, lists and values to decode at once (at most {MAX_OBJECTS} "
            f"units, a map or list counting {CONTAINER_COST} and each entry 1); send fewer values "
            "per message") from None
    except ValueError as e:
        if "exceeds max" in str(e):  # one of msgpack's own length limits
            raise TooLargeError(
                f"message has a string, list or map longer than the protocol allows ({MAX_STR} bytes, "
                f"{MAX_ARRAY} list entries, {MAX_MAP} map keys): split or shrink it") from None
        raise MalformedError("message is not valid msgpack; send one msgpack map per frame") from None
    except Exception:
        raise MalformedError("message is not valid msgpack; send one msgpack map per frame") from None
    return raw


def decode_envelope(frame: bytes) -> tuple[dict[str, Any], int]:
    """Check size and msgpack shape; return the raw map and its request id (0 if unknown).

    Raises a :class:`RoboCompError` whose reply should go to request id 0 when the id
    cannot be read.
    """
    raw = decode_frame(frame)
    if type(raw) is not dict:
        raise MalformedError(f"message must be a msgpack map, got {describe_type(raw)}")
    rid = raw.get("id")
    return raw, rid if type(rid) is int else 0
