"""Connection limits of the core's ROUTER: per peer address, in total, and descriptors kept for
the organiser's hosts and the referee.

libzmq accepts every TCP connection and offers no limit on their number; each one holds a file
descriptor of the core. :class:`ConnectionGuard` watches the ROUTER's accepted and closed
connections through a socket monitor, served from the core's own poller, and cuts
(``shutdown``) a new connection at once when its peer address already holds
:attr:`GuardLimits.per_address` connections or the core holds :attr:`GuardLimits.total`. The
ZAP handler asks :meth:`ConnectionGuard.admit` about every principal that proved itself: once
only :attr:`GuardLimits.kept` connections are left, only the referee and the organiser's hosts
get in. The PUB socket (the public feed, no credential) is watched the same way, and a
subscriber that sends more than :data:`PUB_INBOUND` bytes is cut (:meth:`ConnectionGuard.sweep`).
Cuts and refusals are counted per address and logged once a beat (see the core's ``_tick``). A connection that never completes its handshake is closed by libzmq after
:data:`HANDSHAKE_SECONDS` (ZMQ_HANDSHAKE_IVL).
"""
from __future__ import annotations

import contextlib
import logging
import os
import resource
import socket
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import zmq
import zmq.utils.monitor

from robo_comp.protocol.curve import Tallies, Tally

log = logging.getLogger("robo_comp.core.guard")

#: Seconds a connection may take to complete its handshake (a valid credential) before libzmq closes it.
HANDSHAKE_SECONDS = 5.0
#: Descriptors the core keeps for itself (event log, uploads, sandboxes, pictures) below its limit.
FILE_RESERVE = 128
#: Connections from one peer address, at most (a team's machine with one host per robot stays far below).
PER_ADDRESS = 256
#: Connections kept for the referee and the organiser's hosts when the core is nearly full.
KEPT = 64
#: Roles that may use the kept connections.
KEPT_ROLES = frozenset({"referee", "host"})
#: Bytes a subscriber of the PUB socket may send (its subscriptions: a few bytes each) before it is cut.
PUB_INBOUND = 64 << 10
#: Seconds between two looks at what each PUB connection received.
SWEEP_SECONDS = 0.05
# struct tcp_info (linux/tcp.h): tcpi_bytes_received is the u64 at this offset (Linux 4.1 and later).
_TCP_INFO_LEN = 232
_BYTES_RECEIVED = 128


def raise_fd_limit() -> int:
    """Raise this process's soft limit of open files to its hard limit (where allowed); return the
    limit in force."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if hard == resource.RLIM_INFINITY:
        hard = 1 << 20
    if soft == resource.RLIM_INFINITY:
        return hard
    if soft < hard:
        try:
            resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
            soft = hard
        except (ValueError, OSError) as e:
            log.warning("could not raise the open-file limit from %d to %d: %s", soft, hard, e)
    return soft


@dataclass(frozen=True, slots=True)
class GuardLimits:
    """How many connections the ROUTER may hold: ``total`` in all, ``per_address`` per peer
    address, of which the last ``kept`` only for the referee and hosts."""

    total: int
    per_address: int = PER_ADDRESS
    kept: int = KEPT

    @classmethod
    def for_fd_limit(cls, nofile: int, total: int | None = None, per_address: int = PER_ADDRESS) -> GuardLimits:
        """Limits that fit ``nofile`` descriptors (``total`` at most, when given)."""
        room = max(16, nofile - FILE_RESERVE)
        total = min(room, total) if total else room
        return cls(total, per_address, min(KEPT, total // 4))


@dataclass(slots=True)
class ConnectionGuard:
    """Counts the ROUTER's connections (from its monitor) and cuts those over the limits."""

    limits: GuardLimits
    port: int
    monitor: zmq.Socket
    #: Bytes a connection may send to this socket at most (None: no limit): the PUB socket's
    #: subscribers send a few bytes of subscriptions, so a peer sending more is cut (see :meth:`sweep`).
    inbound: int | None = None
    next_sweep: float = 0.0
    #: Open connections: descriptor -> peer address.
    conns: dict[int, str] = field(default_factory=dict)
    per_address: dict[str, int] = field(default_factory=dict)
    cut_total: int = 0
    _tally: Tallies[str] = field(default_factory=Tallies)

    @classmethod
    def watch(cls, sock: zmq.Socket, port: int, limits: GuardLimits, inbound: int | None = None) -> ConnectionGuard:
        """Start watching ``sock`` (bound to ``port``)."""
        mon = sock.get_monitor_socket(zmq.EVENT_ACCEPTED | zmq.EVENT_DISCONNECTED)
        return cls(limits, port, mon, inbound)

    def sweep(self, now: float) -> None:
        """Cut every connection that sent more than :attr:`inbound` bytes (the kernel counts what each
        TCP connection received: ``TCP_INFO``), at most once per :data:`SWEEP_SECONDS`. libzmq keeps
        the parts of an unfinished multipart message until it ends; this bounds what a peer of the
        PUB socket, which needs no credential, can make the core hold."""
        if self.inbound is None or now < self.next_sweep or not self.conns:
            return
        self.next_sweep = now + SWEEP_SECONDS
        for fd, address in list(self.conns.items()):
            with self._peek(fd) as sock:
                if sock is None:
                    continue
                info = sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, _TCP_INFO_LEN)
                if len(info) >= _BYTES_RECEIVED + 8 and struct.unpack_from("=Q", info, _BYTES_RECEIVED)[0] > self.inbound:
                    self._cut(sock, address, f"a subscriber sent more than {self.inbound} bytes")
                    self._closed(fd)  # counted as gone now: a cut connection is not cut twice

    @property
    def sweeping(self) -> bool:
        """Whether the core's loop must wake up for :meth:`sweep` (connections to look at)."""
        return self.inbound is not None and bool(self.conns)

    @property
    def open(self) -> int:
        """Connections the ROUTER holds now."""
        return len(self.conns)

    def serve(self) -> int:
        """Handle every waiting monitor event without blocking; return how many."""
        n = 0
        while True:
            try:
                frames = self.monitor.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return n
            n += 1
            event = zmq.utils.monitor.parse_monitor_message(frames)
            fd = int(event["value"])
            if event["event"] == zmq.EVENT_ACCEPTED:
                self._accepted(fd)
            elif event["event"] == zmq.EVENT_DISCONNECTED:
                self._closed(fd)

    @contextlib.contextmanager
    def _peek(self, fd: int) -> Iterator[socket.socket | None]:
        """A duplicate of libzmq's descriptor ``fd`` while it is a connection to this socket's port
        (None: closed again, or the number reused by another socket), closed afterwards; libzmq's
        own descriptor stays until libzmq closes it. An ``OSError`` inside (the peer went away
        meanwhile) ends the look quietly."""
        try:
            sock = socket.socket(fileno=os.dup(fd))
        except OSError:
            yield None
            return
        try:
            ours = sock.getsockname()[1] == self.port
        except OSError:
            ours = False
        try:
            yield sock if ours else None
        except OSError:
            pass
        finally:
            sock.close()

    def _accepted(self, fd: int) -> None:
        with self._peek(fd) as sock:
            if sock is None:
                return
            address = str(sock.getpeername()[0])
            self._closed(fd)  # a descriptor number reused before its close was seen
            self.conns[fd] = address
            n = self.per_address.get(address, 0) + 1
            self.per_address[address] = n
            if n > self.limits.per_address:
                self._cut(sock, address, f"more than {self.limits.per_address} connections from one address")
            elif len(self.conns) > self.limits.total:
                self._cut(sock, address, f"the core holds its limit of {self.limits.total} connections")

    def _cut(self, sock: socket.socket, address: str, reason: str) -> None:
        """End a connection (libzmq sees it close and reports it as disconnected)."""
        with contextlib.suppress(OSError):
            sock.shutdown(socket.SHUT_RDWR)
        self.cut_total += 1
        self.count(address, reason)

    def _closed(self, fd: int) -> None:
        address = self.conns.pop(fd, None)
        if address is not None:
            self._forget_address(address)

    def _forget_address(self, address: str) -> None:
        left = self.per_address.get(address, 0) - 1
        if left > 0:
            self.per_address[address] = left
        else:
            self.per_address.pop(address, None)

    def admit(self, principal: Any) -> str | None:
        """For the ZAP handler: None lets a principal that proved itself in, a sentence refuses it
        (only the referee and hosts may use the last ``kept`` connections)."""
        if len(self.conns) > self.limits.total - self.limits.kept and principal_role(principal) not in KEPT_ROLES:
            return (f"the core is full ({len(self.conns)} connections): the last {self.limits.kept} are kept "
                    "for the referee and the organiser's hosts")
        return None

    def count(self, address: str, reason: str) -> None:
        """Count a cut or refused connection of ``address`` for the next bulk log."""
        self._tally.add(address, reason)

    @property
    def cuts_waiting(self) -> bool:
        """Whether connections were cut since the last :meth:`take_cut`."""
        return bool(self._tally)

    def take_cut(self) -> dict[str, Tally]:
        """The cuts since the last call, per address, and start counting anew."""
        return self._tally.take()

    def close(self) -> None:
        """Close the monitor socket (before the ROUTER)."""
        self.monitor.close(0)


def principal_role(principal: Any) -> str:
    """The role of a principal (a CurveZMQ key's owner is a name: ``referee`` or a team)."""
    if isinstance(principal, str):
        return "referee" if principal == "referee" else "team"
    return str(getattr(principal, "role", "team"))


__all__ = ["ConnectionGuard", "GuardLimits", "HANDSHAKE_SECONDS", "KEPT", "PER_ADDRESS", "PUB_INBOUND", "Tally",
           "principal_role", "raise_fd_limit"]
