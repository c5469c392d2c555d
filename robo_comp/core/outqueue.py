"""What the core sends, and when: nothing acknowledged before the log holds what it caused.

Every reply, push and event the core makes in a turn of its loop waits in an :class:`OutQueue`
until :meth:`OutQueue.commit` has flushed the event log (and, with ``--fsync``, forced it to disk):
an acknowledged event survives ``kill -9`` of the core. While the log cannot be written (a full
disk), only urgent frames leave (heartbeats, stops, refusals, reads, unlogged feed events); the
others are held until the records they acknowledge are in the log. A route whose connection went
away gets nothing until its session proves itself there again.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

import zmq

from robo_comp.core.eventlog import EventLog, StorageFault

log = logging.getLogger("robo_comp.core")

#: Frames held back while the log cannot be written, at most (the oldest go first).
HELD_FRAMES = 50_000

Entry = tuple[zmq.Socket, list[bytes], bool]


class OutQueue:
    """Frames waiting for the log flush (see the module docstring). ``sessions`` are the core's
    (a failed send to one of theirs makes its route unproven); ``emit`` tells the world about the
    log's state (``core.storage``); ``stats`` counts what was dropped."""

    def __init__(self, stats: dict[str, Any], sessions: dict[bytes, Any], emit: Callable[..., None]) -> None:
        self.stats = stats
        self.sessions = sessions
        self.emit = emit
        self.out: list[Entry] = []
        self.held: list[Entry] = []
        #: An urgent frame (a stop, its answer) is queued: the loop sends before handling more.
        self.urgent = False
        #: Why the event log cannot be written now (None while it can).
        self.storage_fault: str | None = None
        self.fault_since = 0.0
        #: Routes whose connection went away (a send found no peer).
        self.unproven: set[bytes] = set()
        #: True while a proved message may take the core's short path (no unproven route, no fault).
        self.plain = True

    def replan(self) -> None:
        """Whether the core's short path may serve proved messages (see :attr:`plain`)."""
        self.plain = not self.unproven and self.storage_fault is None

    def proved(self, ident: bytes) -> None:
        """A session proved itself on route ``ident`` (or is gone): pushes may go there again."""
        if self.unproven:
            self.unproven.discard(ident)
            self.replan()

    def push(self, sock: zmq.Socket, ident: bytes, frame: bytes, urgent: bool = False) -> None:
        """Queue a frame for route ``ident`` (a push, or a reply that comes later); nothing for a
        route that is not proved."""
        if self.unproven and ident in self.unproven:
            self.stats["unrouted"] += 1
            return
        if urgent:
            self.urgent = True
        self.out.append((sock, [ident, frame], urgent))

    def reply(self, sock: zmq.Socket, ident: bytes, frame: bytes) -> None:
        """Queue the reply to the message that just came from ``ident``. During a storage fault it
        leaves at once: only requests that log nothing are served then."""
        self.out.append((sock, [ident, frame], self.storage_fault is not None))

    def publish(self, sock: zmq.Socket, frames: list[bytes], urgent: bool) -> None:
        """Queue an event for the PUB socket."""
        self.out.append((sock, frames, urgent))

    def commit(self, events: EventLog) -> None:
        """Flush the event log, then send every queued frame (or, while the log cannot be
        written, the urgent ones, holding the rest)."""
        self.urgent = False
        try:
            events.flush()
        except StorageFault as fault:
            if self.storage_fault is None:
                self._failed(fault)
            out = [entry for entry in self.out if entry[2]]
            self.held.extend(entry for entry in self.out if not entry[2])
            self.out = []
            if len(self.held) > HELD_FRAMES:  # bounded: the oldest pushes go (replies time out)
                self.stats["dropped"] += len(self.held) - HELD_FRAMES
                del self.held[:len(self.held) - HELD_FRAMES]
        else:
            if self.storage_fault is not None:
                self._restored(events)
            out, self.held, self.out = self.held + self.out, [], []
        for sock, frames, _urgent in out:
            try:
                sock.send_multipart(frames, zmq.NOBLOCK)
            except zmq.Again:  # a peer's queue is full (slow consumer): drop, never block the loop
                self.stats["dropped"] += 1
            except zmq.ZMQError as e:
                if e.errno == zmq.EHOSTUNREACH and frames[0] in self.sessions:
                    # the session's connection is gone: whoever presents this id next must prove it
                    self.unproven.add(frames[0])
                    self.plain = False
                log.debug("send failed: %s", e)

    def _failed(self, fault: StorageFault) -> None:
        """The log cannot be written: the core refuses what must be logged until it can."""
        self.storage_fault = (f"the core cannot write its event log ({fault}): until it can, it refuses what "
                              "would change the match (E_STORAGE); reads, stops and heartbeats go on. "
                              "Organiser: free space on the state folder's disk (or fix it); the core goes on "
                              "by itself")
        self.fault_since = time.monotonic()
        self.plain = False
        self.stats["storage_faults"] = self.stats.get("storage_faults", 0) + 1
        log.error("%s", self.storage_fault)
        self.emit("core.storage", None, {"ok": False, "message": self.storage_fault, "errno": fault.errno},
                  log_it=False)

    def _restored(self, events: EventLog) -> None:
        seconds = time.monotonic() - self.fault_since
        self.storage_fault = None
        self.replan()
        log.warning("the event log is written again after %.1f s", seconds)
        self.emit("core.storage", None, {"ok": True, "seconds": round(seconds, 3),
                                         "message": f"the event log is written again (after {seconds:.1f} s)"})
        try:
            events.flush()  # the event above
        except StorageFault:
            pass  # full again at once: the next turn notices


__all__ = ["HELD_FRAMES", "OutQueue"]
