"""Hand-made ZMTP 3.0 for attack tests and benches: a raw TCP peer that speaks just enough of
ZeroMQ's wire protocol to reach the core's ROUTER below pyzmq (greeting, commands, frames), and
the core's memory read from ``/proc``."""
from __future__ import annotations

import json
import socket
import struct
from pathlib import Path
from urllib.parse import urlparse


def zmtp_greeting(mechanism: str = "NULL", as_server: bool = False) -> bytes:
    """The 64-byte ZMTP 3.0 greeting with ``mechanism`` (NULL, PLAIN or CURVE)."""
    return (b"\xff" + b"\0" * 8 + b"\x7f" + bytes([3, 0]) + mechanism.encode().ljust(20, b"\0")
            + bytes([1 if as_server else 0]) + b"\0" * 31)


def zmtp_frame(body: bytes, more: bool = False, command: bool = False) -> bytes:
    """One ZMTP frame: flags (MORE, LONG, COMMAND), size, body."""
    flags = (0x01 if more else 0) | (0x04 if command else 0)
    if len(body) > 255:
        return struct.pack(">BQ", flags | 0x02, len(body)) + body
    return struct.pack(">BB", flags, len(body)) + body


def zmtp_command(name: bytes, properties: dict[bytes, bytes] | None = None, body: bytes = b"") -> bytes:
    """A ZMTP command frame: its name, then ``properties`` (name, value) as metadata, or ``body``."""
    data = bytes([len(name)]) + name + body
    for key, value in (properties or {}).items():
        data += bytes([len(key)]) + key + struct.pack(">I", len(value)) + value
    return zmtp_frame(data, command=True)


def zmtp_plain_hello(user: bytes, password: bytes) -> bytes:
    """A PLAIN ``HELLO`` command (then an ``INITIATE`` completes the client's side)."""
    return zmtp_command(b"HELLO", body=bytes([len(user)]) + user + bytes([len(password)]) + password)


def zmtp_open(mechanism: str = "NULL", password: bytes | None = None) -> bytes:
    """What a DEALER sends first to open a connection, in one piece: the greeting, then READY
    (NULL: the handshake is then complete) or HELLO with ``password`` (PLAIN: libzmq closes a
    connection whose INITIATE comes before its WELCOME, so :func:`zmtp_initiate` follows once
    ``WELCOME`` has arrived; :func:`zmtp_plain_handshake` does both)."""
    if mechanism == "PLAIN":
        return zmtp_greeting("PLAIN") + zmtp_plain_hello(b"robo_comp", password or b"")
    return zmtp_greeting("NULL") + zmtp_command(b"READY", {b"Socket-Type": b"DEALER"})


def zmtp_null_handshake(sock: socket.socket, socket_type: bytes = b"DEALER") -> None:
    """Complete a NULL handshake as a ``socket_type`` peer on a connected blocking ``sock``: the
    greeting and ``READY``, then wait for the other side's ``READY``. (libzmq 4.3 closes a
    connection whose first frames arrive in the same read as its handshake, so frames sent
    before this returns may be cut by libzmq rather than by what a test means to check.)
    :class:`ConnectionError` if the other side closes the connection instead."""
    sock.sendall(zmtp_greeting("NULL") + zmtp_command(b"READY", {b"Socket-Type": socket_type}))
    zmtp_expect(sock, b"READY")


def zmtp_expect(sock: socket.socket, word: bytes) -> None:
    """Read from a connected blocking ``sock`` until ``word`` has come (a command's name, a reply's
    error code); :class:`ConnectionError` if the other side closes the connection first."""
    got = b""
    while word not in got:
        chunk = sock.recv(4096)
        if not chunk:
            raise ConnectionError(f"the other side closed the connection before {word.decode(errors='replace')}")
        got += chunk


def zmtp_initiate() -> bytes:
    """A PLAIN client's ``INITIATE`` as a DEALER, sent after the server's ``WELCOME``."""
    return zmtp_command(b"INITIATE", {b"Socket-Type": b"DEALER"})


def zmtp_plain_handshake(sock: socket.socket, password: bytes) -> None:
    """Complete a PLAIN handshake on a connected blocking ``sock`` (the core then hands this
    peer's messages to its loop); :class:`ConnectionError` if the core closes it instead."""
    sock.sendall(zmtp_open("PLAIN", password))
    zmtp_expect(sock, b"WELCOME")
    sock.sendall(zmtp_initiate())
    zmtp_expect(sock, b"READY")


def router_address(state: Path) -> tuple[str, int]:
    """(host, port) of the ROUTER of the core whose state folder is ``state``."""
    url = urlparse(json.loads((Path(state) / "core.json").read_text())["router"])
    assert url.hostname is not None and url.port is not None
    return url.hostname, url.port


def _core_status(state: Path, field: str) -> int:
    """A memory figure (``VmRSS``, ``VmHWM``) of the core process whose state folder is ``state``, in bytes (Linux)."""
    pid = json.loads((Path(state) / "core.json").read_text())["pid"]
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) * 1024
    raise RuntimeError(f"no {field} for process {pid}")


def core_rss(state: Path) -> int:
    """Resident memory, in bytes, of the core process whose state folder is ``state`` (Linux)."""
    return _core_status(state, "VmRSS")


def reset_core_peak(state: Path) -> None:
    """Start the core's peak resident memory (:func:`core_peak`) anew from what it holds now
    (Linux's ``/proc/PID/clear_refs``, the same user's process)."""
    pid = json.loads((Path(state) / "core.json").read_text())["pid"]
    Path(f"/proc/{pid}/clear_refs").write_text("5")


def core_peak(state: Path) -> int:
    """The most resident memory, in bytes, the core process whose state folder is ``state`` held
    since it started or since :func:`reset_core_peak` (``VmHWM``): a bound that held only between
    two samples still shows."""
    return _core_status(state, "VmHWM")


__all__ = ["core_peak", "core_rss", "reset_core_peak", "router_address", "zmtp_command", "zmtp_frame", "zmtp_greeting",
           "zmtp_expect", "zmtp_initiate", "zmtp_null_handshake", "zmtp_open", "zmtp_plain_handshake", "zmtp_plain_hello"]
