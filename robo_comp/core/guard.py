"""Connection limits of the core's ROUTER: per peer address, in total, descriptors kept for the
organiser's hosts and the referee, and what each connection may make the core hold.

libzmq accepts every TCP connection and offers no limit on their number; each one holds a file
descriptor of the core. :class:`ConnectionGuard` watches the ROUTER's accepted and closed
connections through a socket monitor, served from the core's own poller, and cuts
(``shutdown``) a new connection at once when its peer address already holds
:attr:`GuardLimits.per_address` connections or the core holds :attr:`GuardLimits.total`. The
ZAP handler asks :meth:`ConnectionGuard.admit` about every principal that proved itself: once
only :attr:`GuardLimits.kept` connections are left, only the referee and the organiser's hosts
get in. The PUB socket (the public feed, no credential) is watched the same way, and a
subscriber that sends more than :data:`PUB_INBOUND` bytes is cut (:meth:`ConnectionGuard.sweep`).
Cuts and refusals are counted per address and logged once a beat (see the core's ``_tick``). A
connection that never completes its handshake is closed by libzmq after :data:`HANDSHAKE_SECONDS`
(ZMQ_HANDSHAKE_IVL).

**What a connection holds.** libzmq reads each connection as fast as it can and keeps the parts
of a multipart message until its last part comes: ZMQ_MAXMSGSIZE bounds one part, nothing bounds
their number, and the core is handed nothing of the message until it ends. So the core counts,
per connection (descriptor), what it was handed (:meth:`ConnectionGuard.took`, each message's
ZMQ_SRCFD, its frames' size on the wire) and, every :data:`LOOK_SECONDS`, asks the kernel what
libzmq has read off that connection (``TCP_INFO``'s bytes received less those still unread,
``FIONREAD``). The difference, less the handshake and the answers to libzmq's own pings, is what
the connection holds in the core. A connection is cut that holds more than
:data:`HOLD_UNFINISHED` (one whole frame and some) the core cannot have been handed yet, or more
than :data:`HOLD_MAX` in any way; and, once those the core took nothing from since the last look
hold more than :data:`HOLD_TOTAL` together, the biggest of them (see
:meth:`ConnectionGuard.sweep`). libzmq frees what a connection held when it closes.
``docs/security.md`` says what remains.
"""
from __future__ import annotations

import array
import contextlib
import ctypes
import fcntl
import logging
import os
import resource
import socket
import struct
import termios
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import zmq
import zmq.utils.monitor

from robo_comp.protocol.curve import Tallies, Tally
from robo_comp.protocol.wire import SOCKET_MAX_FRAME

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
#: Seconds between two sweeps: a glance at the core's own resident memory, and a look at what each
#: connection received when one is due (see :meth:`ConnectionGuard.sweep`).
SWEEP_SECONDS = 0.01
#: Seconds between two looks at what each connection received (longer when looking takes more than
#: :data:`LOOK_SHARE` of the core's time).
LOOK_SECONDS = 0.05
#: The share of the core's time its regular looks at the connections may take: after a look that
#: took t seconds, the next comes :data:`LOOK_SECONDS` or t / LOOK_SHARE later, whichever is longer.
LOOK_SHARE = 0.02
#: Bytes the core's resident memory may grow above its lowest since the last look before the next
#: look comes at once (at most :data:`GROWTH_SHARE` of the core's time): a peer holding memory as
#: fast as loopback carries it is looked at within a sweep, not within :data:`LOOK_SECONDS`.
LOOK_GROWTH = 4 << 20
#: The share of the core's time looks brought forward by memory growth may take.
GROWTH_SHARE = 0.1
#: Bytes a connection may hold of a message the core cannot have been handed yet (read off the
#: socket by libzmq, nothing complete waiting for the core): one whole frame of the largest size
#: libzmq lets through (ZMQ_MAXMSGSIZE, 1 MiB + 64 KiB) and one read more, with room to spare.
HOLD_UNFINISHED = SOCKET_MAX_FRAME + (128 << 10)
#: Bytes a connection may hold however it holds them (complete messages the core has not taken yet
#: included: an honest client's backlog behind a core stalled for seconds is far smaller).
HOLD_MAX = 16 << 20
#: Bytes the connections the core was handed nothing from since the last look may hold together;
#: past it the biggest holders are cut first.
HOLD_TOTAL = 16 << 20
#: Bytes of its handshake a connection may send without holding anything (greeting, HELLO,
#: INITIATE and their metadata: a few hundred bytes for the project's clients).
HANDSHAKE_ROOM = 4 << 10
#: Bytes on the wire an answer (PONG) to one of the core's pings costs its peer: a command frame
#: ``\x04PONG`` with no context (the core's pings carry none), and under CurveZMQ that sealed in a
#: MESSAGE (see :data:`CURVE_FRAME_EXTRA`).
PONG_BYTES = 7
#: Bytes CurveZMQ adds to each frame on the wire: a MESSAGE command (its name 8, nonce 8, MAC 16
#: and the flags byte 1) around the frame's body (libzmq 4.3's ``curve_encoding_t::encode``).
CURVE_FRAME_EXTRA = 33
#: libzmq's context option ZMQ_ZERO_COPY_RECV (a draft name pyzmq does not export; libzmq 4.3 takes it).
ZERO_COPY_RECV = 10
# struct tcp_info (linux/tcp.h): tcpi_bytes_received is the u64 at this offset (Linux 4.1 and later).
_TCP_INFO_LEN = 232
_BYTES_RECEIVED = 128
# Bytes a look counts as held without asking how many the kernel still has unread (an honest
# connection's answer to the last ping, say: a few bytes); past it, it asks.
_EXACT_ABOVE = 4096
_SRCFD = int(zmq.SRCFD)  # a plain int: Frame.get takes it a little faster than the enum


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


def copy_received(ctx: zmq.Context) -> None:
    """Make libzmq copy each received frame into memory of its own (ZMQ_ZERO_COPY_RECV off) in
    sockets ``ctx`` makes from now on. By default a frame of 33 bytes or more points into the
    8 KiB receive buffer it was read into, which stays allocated while any such frame lives: a
    peer sending one small part of an unfinished message per read made the core hold over 100
    times what it sent (measured with libzmq 4.3.5); copied, a part holds its own size and a
    64-byte header. Costs one copy of each frame in libzmq's I/O thread."""
    try:
        ctx.set(ZERO_COPY_RECV, 0)
    except zmq.ZMQError as e:  # a libzmq without the option: receive buffers stay shared
        log.warning("libzmq %s cannot copy received frames (%s): a connection's held bytes may cost more memory",
                    zmq.zmq_version(), e)


class _Kernel:
    """What the kernel counts of a TCP connection, read through libzmq's descriptor in place (no
    duplicate descriptor, no Python socket: a look costs a system call or two a connection), and
    this process's resident memory. Whether a descriptor is still the connection it was (its port
    and its peer) is checked only before a cut (:meth:`ConnectionGuard._peek`): a number reused
    meanwhile reads as another socket's counts at worst, or as nothing."""

    def __init__(self) -> None:
        self._getsockopt = ctypes.CDLL(None, use_errno=True).getsockopt
        self._info = ctypes.create_string_buffer(_TCP_INFO_LEN)
        self._info_len = ctypes.c_uint32()
        self._info_len_p = ctypes.byref(self._info_len)
        self._unread = array.array("i", [0])
        self._statm: int | None = None
        self._page = os.sysconf("SC_PAGE_SIZE")

    def received(self, fd: int) -> int | None:
        """Bytes the TCP connection on descriptor ``fd`` received (``TCP_INFO``), or None (not a TCP
        connection, or closed)."""
        self._info_len.value = _TCP_INFO_LEN
        if (self._getsockopt(fd, socket.IPPROTO_TCP, socket.TCP_INFO, self._info, self._info_len_p) != 0
                or self._info_len.value < _BYTES_RECEIVED + 8):
            return None
        received: int = struct.unpack_from("=Q", self._info, _BYTES_RECEIVED)[0]
        return received

    def unread(self, fd: int) -> int:
        """Bytes the connection on descriptor ``fd`` received that nobody read yet (``FIONREAD``; 0
        if it cannot say)."""
        try:
            fcntl.ioctl(fd, termios.FIONREAD, self._unread)
        except OSError:
            return 0
        return self._unread[0]

    def resident(self) -> int:
        """This process's resident memory in bytes (``/proc/self/statm``, kept open)."""
        if self._statm is None:
            self._statm = os.open("/proc/self/statm", os.O_RDONLY | os.O_CLOEXEC)
        return int(os.pread(self._statm, 128, 0).split()[1]) * self._page


_kernel: _Kernel | None = None


def _the_kernel() -> _Kernel:
    global _kernel
    if _kernel is None:
        _kernel = _Kernel()
    return _kernel


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
class Holding:
    """What the guard knows of one connection's bytes between its looks (see :meth:`ConnectionGuard.sweep`)."""

    #: When it was last looked at (or accepted).
    looked: float
    #: Bytes read off it that hold nothing in the core although never handed to it: its handshake
    #: and its answers to the core's pings. Lowered to what it used whenever it holds nothing.
    allowed: float = HANDSHAKE_ROOM
    #: Bytes the core had been handed of it at the last look.
    seen: int = 0
    #: Whether it held more than :data:`HOLD_UNFINISHED` at the last look.
    over: bool = False


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
    #: When the core's memory is glanced at next, the earliest a look may come for its growth, and the
    #: lowest resident memory since the last look (see :meth:`sweep`).
    next_glance: float = 0.0
    next_forced: float = 0.0
    floor: int = 0
    #: Open connections: descriptor -> peer address.
    conns: dict[int, str] = field(default_factory=dict)
    #: Per descriptor, the peer's (address, port) when it was accepted: a cut checks that the
    #: descriptor is still that connection (libzmq may have closed it and given the number to a new one).
    peers: dict[int, tuple[str, int]] = field(default_factory=dict)
    per_address: dict[str, int] = field(default_factory=dict)
    cut_total: int = 0
    #: The watched socket, when the guard bounds what its connections hold (the ROUTER; see :meth:`took`).
    holder: zmq.Socket | None = None
    #: Bytes on the wire of what the core was handed, per descriptor (:meth:`took`).
    handed: dict[int, int] = field(default_factory=dict)
    #: Per descriptor, what the last look found (:meth:`sweep`).
    holding: dict[int, Holding] = field(default_factory=dict)
    #: Bytes the socket's security mechanism adds to each frame on the wire (CurveZMQ: 33).
    frame_extra: int = 0
    #: Bytes on the wire of a peer's answer to one of the socket's pings, and seconds between those pings (0: none).
    pong_bytes: int = PONG_BYTES
    ping_seconds: float = 0.0
    _tally: Tallies[str] = field(default_factory=Tallies)

    @classmethod
    def watch(cls, sock: zmq.Socket, port: int, limits: GuardLimits, inbound: int | None = None,
              hold: bool = False) -> ConnectionGuard:
        """Start watching ``sock`` (bound to ``port``); with ``hold``, also bound what each of its
        connections holds (the core then tells :meth:`took` every message it receives). Read its
        security mechanism and heartbeat after setting them."""
        mon = sock.get_monitor_socket(zmq.EVENT_ACCEPTED | zmq.EVENT_DISCONNECTED)
        guard = cls(limits, port, mon, inbound)
        if hold:
            guard.holder = sock
            if sock.get(zmq.MECHANISM) == zmq.CURVE:
                guard.frame_extra = CURVE_FRAME_EXTRA
                guard.pong_bytes = PONG_BYTES + CURVE_FRAME_EXTRA
            guard.ping_seconds = max(0, int(sock.get(zmq.HEARTBEAT_IVL))) / 1000
        return guard

    def took(self, first: zmq.Frame, frames: list[bytes]) -> None:
        """Count a message the core received: ``first`` the frame the ROUTER handed first (whose
        ZMQ_SRCFD names the connection), ``frames`` all of them as bytes, the routing id first (which
        never crossed the wire). Each frame counts as it travelled: its body, what the security
        mechanism adds, and a ZMTP header of 2 bytes (9 past 255), never more than the peer sent.
        On the core's report path: about 0.25 µs a message."""
        try:
            fd = first.get(_SRCFD)
        except zmq.ZMQError:  # no descriptor (not a TCP connection): nothing to weigh it against
            return
        extra = self.frame_extra
        if len(frames) == 2:  # the protocol's one frame (the common case, kept short)
            n = len(frames[1]) + extra
            wire = n + 2 if n < 256 else n + 9
        else:
            wire = 0
            for frame in frames[1:]:
                n = len(frame) + extra
                wire += n + 2 if n < 256 else n + 9
        handed = self.handed
        handed[fd] = handed.get(fd, 0) + wire

    def sweep(self, now: float) -> None:
        """Look at what each connection received, once per :data:`LOOK_SECONDS` (less often when
        looking takes more than :data:`LOOK_SHARE` of the core's time), and at once when the core's
        resident memory, glanced at every :data:`SWEEP_SECONDS`, grew :data:`LOOK_GROWTH` above its
        lowest since the last look. On the PUB socket, cut a connection that sent more than
        :attr:`inbound` bytes. On the ROUTER (:meth:`watch` with ``hold``), cut a connection whose
        bytes read off it by libzmq, less those handed to the core, its handshake and its answers to
        pings, are more than

        * :data:`HOLD_UNFINISHED` while the core has no complete message waiting (so none of those
          bytes can be a message the core merely has not taken yet: they are parts of an
          unfinished one), or at two looks in a row with nothing handed in between;
        * :data:`HOLD_MAX` in any case;

        and, while those the core was handed nothing from since the last look together hold more than
        :data:`HOLD_TOTAL`, the biggest of them."""
        if not self.sweeping:
            return
        if now < self.next_sweep:
            if now < self.next_glance:
                return
            self.next_glance = now + SWEEP_SECONDS
            resident = _the_kernel().resident()
            self.floor = min(self.floor, resident)
            if resident <= self.floor + LOOK_GROWTH or now < self.next_forced:
                return
        started = time.perf_counter()
        if self.inbound is not None:
            kernel = _the_kernel()
            for fd, address in list(self.conns.items()):
                received = kernel.received(fd)
                if received is not None and received > self.inbound:
                    self._cut_fd(fd, address, f"a subscriber sent more than {self.inbound} bytes")
        if self.holder is not None:
            self._look_held(now)
        took = time.perf_counter() - started
        self.next_sweep = now + max(LOOK_SECONDS, took / LOOK_SHARE)
        self.next_forced = now + took / GROWTH_SHARE
        self.floor = _the_kernel().resident()

    def _look_held(self, now: float) -> None:
        assert self.holder is not None
        kernel = _the_kernel()
        handed_of = self.handed.get
        credit = self.pong_bytes / self.ping_seconds if self.ping_seconds else 0.0  # bytes a second
        rows: list[tuple[float, int, bool]] = []
        for fd, h in self.holding.items():
            received = kernel.received(fd)
            if received is None:
                continue
            handed = handed_of(fd, 0)
            stuck = handed == h.seen
            h.seen = handed
            allowed = h.allowed + credit * (now - h.looked)
            h.looked = now
            held = received - handed - allowed
            if held > _EXACT_ABOVE:  # (the common case, next to nothing, needs no second call)
                held -= kernel.unread(fd)  # read after the bytes received: never more than libzmq read
            if held <= 0:  # all it sent was handed or allowed: what it was allowed and did not use is not kept
                h.allowed = allowed + held
                h.over = False
                continue
            h.allowed = allowed
            rows.append((held, fd, stuck))
        # after the counts: a message complete by then is handed or waiting now (only one read per
        # connection, at most a frame, can be read and not yet passed on by libzmq's I/O thread)
        waiting = bool(int(self.holder.get(zmq.EVENTS)) & zmq.POLLIN)
        total = 0.0
        kept: list[tuple[float, int]] = []
        for held, fd, stuck in rows:  # those that hold something
            h = self.holding[fd]
            if held > HOLD_MAX:
                self._cut_fd(fd, self.conns.get(fd, "?"), f"it held {held / (1 << 20):.1f} MiB the core had not "
                             f"taken, over {HOLD_MAX >> 20} MiB")
            elif held > HOLD_UNFINISHED and not waiting:
                self._cut_fd(fd, self.conns.get(fd, "?"), f"it held {held / (1 << 20):.1f} MiB of a message it did "
                             f"not finish, over {HOLD_UNFINISHED / (1 << 20):.2f} MiB")
            elif held > HOLD_UNFINISHED and stuck and h.over:
                self._cut_fd(fd, self.conns.get(fd, "?"), f"it held {held / (1 << 20):.1f} MiB the core was not "
                             f"handed at two looks in a row, over {HOLD_UNFINISHED / (1 << 20):.2f} MiB")
            else:
                h.over = held > HOLD_UNFINISHED
                if stuck:  # (one the core keeps taking from holds a backlog at most, bounded by HOLD_MAX)
                    total += held
                    kept.append((held, fd))
        if total > HOLD_TOTAL:
            for held, fd in sorted(kept, reverse=True):
                self._cut_fd(fd, self.conns.get(fd, "?"), f"connections the core took nothing from held "
                             f"{total / (1 << 20):.0f} MiB together, over {HOLD_TOTAL >> 20} MiB, and it held the most "
                             f"({held / (1 << 20):.1f} MiB)")
                total -= held
                if total <= HOLD_TOTAL:
                    break

    @property
    def sweeping(self) -> bool:
        """Whether the core's loop must wake up for :meth:`sweep` (connections to look at)."""
        return (self.inbound is not None or self.holder is not None) and bool(self.conns)

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
    def _peek(self, fd: int, peer: tuple[str, int] | None = None) -> Iterator[socket.socket | None]:
        """A duplicate of libzmq's descriptor ``fd`` while it is a connection to this socket's port,
        and with ``peer`` given, the connection from that (address, port) (None: closed again, or the
        number reused by another socket or another connection), closed afterwards; libzmq's own
        descriptor stays until libzmq closes it. An ``OSError`` inside (the peer went away
        meanwhile) ends the look quietly."""
        try:
            sock = socket.socket(fileno=os.dup(fd))
        except OSError:
            yield None
            return
        try:
            ours = sock.getsockname()[1] == self.port
            if ours and peer is not None:
                ours = tuple(sock.getpeername()[:2]) == peer
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
            name = sock.getpeername()
            address = str(name[0])
            # a descriptor number reused before its close was seen; what the core was handed from
            # it is kept (a message may be received before its connection's accept is seen here)
            early = self.handed.pop(fd, 0)
            self._closed(fd)
            self.conns[fd] = address
            self.peers[fd] = (address, int(name[1]))
            if self.holder is not None:
                self.handed[fd] = early
                self.holding[fd] = Holding(time.monotonic(), seen=early)
            n = self.per_address.get(address, 0) + 1
            self.per_address[address] = n
            if n > self.limits.per_address:
                self._cut(sock, address, f"more than {self.limits.per_address} connections from one address")
            elif len(self.conns) > self.limits.total:
                self._cut(sock, address, f"the core holds its limit of {self.limits.total} connections")

    def _cut(self, sock: socket.socket, address: str, reason: str) -> None:
        """End a connection (libzmq sees it close and reports it as disconnected). With a linger of
        0 libzmq's close then resets it, so a peer whose sends filled the core's receive window
        learns at once, not after its zero-window probes time out."""
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            sock.shutdown(socket.SHUT_RDWR)
        self.cut_total += 1
        self.count(address, reason)

    def _cut_fd(self, fd: int, address: str, reason: str) -> None:
        """Cut the connection on descriptor ``fd`` and count it as gone now (a cut connection is not
        cut twice); libzmq then frees what it held. A descriptor that is no longer the connection
        accepted under that number (libzmq closed it and gave the number to a new connection since
        the guard's look) is not cut: the new connection is another peer."""
        with self._peek(fd, self.peers.get(fd)) as sock:
            if sock is not None:
                self._cut(sock, address, reason)
        self._closed(fd)

    def _closed(self, fd: int) -> None:
        self.peers.pop(fd, None)
        self.holding.pop(fd, None)
        self.handed.pop(fd, None)
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


__all__ = ["ConnectionGuard", "GuardLimits", "HANDSHAKE_SECONDS", "HOLD_MAX", "HOLD_TOTAL", "HOLD_UNFINISHED",
           "Holding", "KEPT", "PER_ADDRESS", "PUB_INBOUND", "Tally", "copy_received", "principal_role",
           "raise_fd_limit"]
