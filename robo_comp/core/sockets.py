"""The core's two sockets, made as the transport's defences need them."""
from __future__ import annotations

import zmq

from robo_comp import protocol as P
from robo_comp.core.guard import HANDSHAKE_SECONDS
from robo_comp.protocol.curve import ServerKeys, secure_plain_server, secure_server

#: Events queued per PUB subscriber before the slowest ones start missing events (ZMQ_SNDHWM).
#: Positions travel conflated (one batch per team per pose period), so 2,000 events are tens of
#: seconds of a 1,000-robot match.
PUB_QUEUE = 2_000


def open_router(ctx: zmq.Context, host: str, port: int, curve: ServerKeys | None,
                heartbeat: float) -> tuple[zmq.Socket, int]:
    """The ROUTER every client talks to, bound on ``host:port`` (0: a free port); returns it and its port.

    Under CurveZMQ with the core's keys, else PLAIN (a token is the password; the ZAP handler checks
    it before libzmq hands the core a byte)."""
    router = ctx.socket(zmq.ROUTER)
    if curve is not None:
        secure_server(router, curve)
    else:
        secure_plain_server(router)
    router.setsockopt(zmq.LINGER, 0)
    router.setsockopt(zmq.MAXMSGSIZE, P.SOCKET_MAX_FRAME)
    # A second connection that presents a routing id in use is ignored by libzmq, never handed
    # the first one's messages (handover would give it the session's pushes and cut the owner off).
    router.setsockopt(zmq.ROUTER_HANDOVER, 0)
    # A send to a route with no connection fails (EHOSTUNREACH) instead of vanishing: the core
    # then stops pushing to that route until its session proves itself there again.
    router.setsockopt(zmq.ROUTER_MANDATORY, 1)
    # Dead connections (a cut cable) are dropped by ZMTP heartbeats, so that their ids free up.
    router.setsockopt(zmq.HEARTBEAT_IVL, int(max(1.0, heartbeat) * 2000))
    router.setsockopt(zmq.HEARTBEAT_TIMEOUT, int(max(1.0, heartbeat) * 10_000))
    # a connection that has not proved a credential within this time is closed by libzmq
    router.setsockopt(zmq.HANDSHAKE_IVL, int(HANDSHAKE_SECONDS * 1000))
    router.setsockopt(zmq.SNDHWM, 100_000)
    router.setsockopt(zmq.RCVHWM, 100_000)
    if port == 0:
        port = router.bind_to_random_port(f"tcp://{host}")
    else:
        router.bind(f"tcp://{host}:{port}")
    return router, port


def open_pub(ctx: zmq.Context, host: str, port: int, curve: ServerKeys | None) -> tuple[zmq.Socket, int]:
    """The PUB socket of the public feed, bound on ``host:port`` (0: a free port); returns it and its port."""
    pub = ctx.socket(zmq.PUB)
    pub.setsockopt(zmq.LINGER, 0)
    # A slow subscriber (a wall on a weak link) gets at most this many events queued for it,
    # then PUB drops for that subscriber only: bounded memory, and the core never waits.
    pub.setsockopt(zmq.SNDHWM, PUB_QUEUE)
    secure_server(pub, curve)
    pub.setsockopt(zmq.MAXMSGSIZE, 1024)  # subscriptions: a topic, a few bytes
    if port == 0:
        port = pub.bind_to_random_port(f"tcp://{host}")
    else:
        pub.bind(f"tcp://{host}:{port}")
    return pub, port


__all__ = ["PUB_QUEUE", "open_pub", "open_router"]
