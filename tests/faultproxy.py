"""A TCP proxy on loopback that delays and stalls a link, for fault tests.

This kernel has no ``sch_netem`` (``tc qdisc add ... netem`` says "Specified qdisc kind is
unknown"), so latency and loss are made where the application sees them: every chunk waits
``delay`` (plus a random ``jitter``) before it is forwarded, in order, and :meth:`stall` holds
everything for a while — what a link that loses every packet looks like to TCP's users (TCP
retransmits; the bytes arrive late and in order, or the peers give up).
"""
from __future__ import annotations

import random
import selectors
import socket
import threading
import time
from collections import deque


class DelayProxy:
    """Listen on a free loopback port; forward each connection to ``target_port``."""

    def __init__(self, target_port: int, delay: float = 0.0, jitter: float = 0.0, seed: int = 0) -> None:
        self.target = ("127.0.0.1", target_port)
        self.delay = delay
        self.jitter = jitter
        self.rng = random.Random(seed)
        self.stalled_until = 0.0
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.listener.setblocking(False)
        self.port = self.listener.getsockname()[1]
        self.sel = selectors.DefaultSelector()
        self.sel.register(self.listener, selectors.EVENT_READ)
        # socket -> (its peer, chunks waiting to be sent to the peer: (release time, bytes))
        self.links: dict[socket.socket, tuple[socket.socket, deque[tuple[float, bytes]]]] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="delay-proxy", daemon=True)

    @property
    def url(self) -> str:
        """Where clients connect instead of the core."""
        return f"tcp://127.0.0.1:{self.port}"

    def start(self) -> DelayProxy:
        self._thread.start()
        return self

    def stall(self, seconds: float) -> None:
        """Hold every byte, both ways, for ``seconds`` (then forward them in order)."""
        self.stalled_until = time.monotonic() + seconds

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        for s in list(self.links):
            s.close()
        self.listener.close()

    def _accept(self) -> None:
        try:
            client, _ = self.listener.accept()
        except BlockingIOError:
            return
        upstream = socket.create_connection(self.target)
        for s in (client, upstream):
            s.setblocking(False)
            s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self.sel.register(s, selectors.EVENT_READ)
        self.links[client] = (upstream, deque())
        self.links[upstream] = (client, deque())

    def _drop(self, s: socket.socket) -> None:
        peer, _ = self.links.pop(s, (None, None))
        for x in (s, peer):
            if x is not None:
                try:
                    self.sel.unregister(x)
                except (KeyError, ValueError):
                    pass
                x.close()
                self.links.pop(x, None)

    def _loop(self) -> None:
        while not self._stop.is_set():
            for key, _ in self.sel.select(0.005):
                s = key.fileobj
                if s is self.listener:
                    self._accept()
                    continue
                if s not in self.links:
                    continue
                try:
                    data = s.recv(65536)  # type: ignore[union-attr]
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError:
                    data = b""
                if not data:
                    self._drop(s)  # type: ignore[arg-type]
                    continue
                _, queue = self.links[s]  # type: ignore[index]
                last = queue[-1][0] if queue else 0.0
                release = max(last, time.monotonic() + self.delay + self.rng.uniform(0, self.jitter))
                queue.append((release, data))
            now = time.monotonic()
            if now < self.stalled_until:
                continue
            for s, (peer, queue) in list(self.links.items()):
                while queue and queue[0][0] <= now:
                    release, data = queue[0]
                    try:
                        sent = peer.send(data)
                    except (BlockingIOError, InterruptedError):
                        break
                    except OSError:
                        self._drop(s)
                        break
                    if sent < len(data):
                        queue[0] = (release, data[sent:])
                        break
                    queue.popleft()
