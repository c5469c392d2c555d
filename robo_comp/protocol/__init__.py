"""The wire protocol every robo_comp process shares: msgpack frames, versioned, with typed fields
and stable error codes. Clients, robot hosts, walls and the core import this package; it imports
nothing of theirs.

- :mod:`~robo_comp.protocol.wire`: the envelope (encoding, decoding, session secret, routing ids);
- :mod:`~robo_comp.protocol.messages`: the message table and the checks run on every message;
- :mod:`~robo_comp.protocol.topics`: the one table of event topics: fields and who may see them;
- :mod:`~robo_comp.protocol.states`: the wire's state words as enums;
- :mod:`~robo_comp.protocol.taskspec`: advertised task descriptions and task-call checks;
- :mod:`~robo_comp.protocol.replies`: the one reply decoder;
- :mod:`~robo_comp.protocol.arena`: reading the arena payload;
- :mod:`~robo_comp.protocol.curve`: CurveZMQ keys and socket security, both ends.

``from robo_comp import protocol as P`` gives the names below. See ``docs/protocol.md``.
"""
from robo_comp.protocol.arena import unpack_walls
from robo_comp.protocol.messages import (
    ANY_ROLE,
    CONSOLE_ONLY,
    CORE_TO_HOST,
    TO_HOST,
    HOST_ONLY,
    MAX_RADIO,
    MAX_REPORTS,
    NOTIFICATIONS,
    OPENING,
    RADIO_RATE,
    REQUESTS,
    ROLE_MESSAGES,
    check_reports,
    decode,
    validate,
    validate_to_host,
)
from robo_comp.protocol.replies import reply_body, reply_error
from robo_comp.protocol.topics import (
    AFTER_MATCH_TOPICS, DEBUG_REPLAY, EVERYONE, PRIVATE_FIELDS, PRIVATE_TOPICS, PUBLIC_TOPICS, TABLE, TOPICS, EventView,
    check_event, public_event, readable, replay_public_event,
)
from robo_comp.protocol.wire import (
    INSTANCE_MAX,
    INSTANCE_MIN,
    MAX_FRAME,
    PROTOCOL_VERSION,
    ROUTING_ID_BYTES,
    SESSION_BYTES,
    SESSION_KEY,
    SOCKET_MAX_FRAME,
    Message,
    decode_envelope,
    describe_type,
    error_reply,
    event_frames,
    is_finite,
    new_instance_id,
    new_routing_id,
    new_session_secret,
    ok_reply,
    pack,
    request,
    unpack,
)

__all__ = [
    "ANY_ROLE", "CONSOLE_ONLY", "HOST_ONLY", "ROLE_MESSAGES", "INSTANCE_MAX", "INSTANCE_MIN",
    "CORE_TO_HOST", "TO_HOST", "validate_to_host", "EVERYONE", "EventView", "MAX_FRAME", "MAX_RADIO", "MAX_REPORTS", "NOTIFICATIONS", "OPENING",
    "AFTER_MATCH_TOPICS", "DEBUG_REPLAY", "PRIVATE_FIELDS", "TABLE", "check_event", "PRIVATE_TOPICS", "PUBLIC_TOPICS", "PROTOCOL_VERSION", "RADIO_RATE", "REQUESTS", "ROUTING_ID_BYTES", "SESSION_BYTES",
    "SESSION_KEY", "SOCKET_MAX_FRAME", "TOPICS", "Message", "check_reports", "decode", "decode_envelope",
    "describe_type", "error_reply", "event_frames", "is_finite", "new_instance_id", "new_routing_id", "new_session_secret",
    "ok_reply", "pack", "public_event", "readable", "replay_public_event", "reply_body", "reply_error", "request", "unpack", "unpack_walls",
    "validate",
]
