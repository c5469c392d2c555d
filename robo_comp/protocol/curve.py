"""Transport security: the core's ZAP handler, PLAIN tokens by default, CurveZMQ for networked
matches (key files, the client socket setup).

Without ``--curve`` every connection to the core's ROUTER is a PLAIN handshake whose password is
the client's token (team, referee, ...): the ZAP handler checks it with the core's token book, and
a peer without a valid token never completes the handshake, so libzmq buffers nothing of it and the
core never decodes a frame of it (:func:`secure_plain_client`, :func:`secure_plain_server`). PLAIN
sends the token in clear, like the ``hello`` that follows: across a network use CurveZMQ.

For a match over a network the organiser runs ``robo-comp keys --state DIR`` once, starts the core with ``--curve`` and hands
each team its secret certificate plus the core's public certificate::

    STATE/keys/core.key            the core's public certificate: goes to everyone
    STATE/keys/core.key_secret     the core's secret certificate: never leaves the core's machine
    STATE/keys/<team>.key_secret   team <team>'s secret certificate: goes to that team only
    STATE/keys/<team>.key          its public half: stays with the core (the allow list)
    STATE/keys/referee.key_secret  the referee's (and the organiser's walls') certificate

A ``--curve`` core makes its ROUTER and PUB sockets CURVE servers. Its :class:`ZapHandler` is a
ZAP REP socket polled in the core's own loop (no hidden thread): it lets a handshake through only
when the client's public key is one of the ``*.key`` files in ``STATE/keys``. A client without
an allowed key never completes the handshake, so it never gets a reply or an event; inside the
encrypted channel the token check stays exactly as without CURVE.

Every socket that connects to a core goes through :func:`secure_client` (CURVE) or
:func:`secure_plain_client` (PLAIN); the core's sockets go through :func:`secure_server`. Clients find their keys with :func:`client_keys`.
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import zmq
import zmq.auth
import zmq.utils.monitor
from zmq.utils import z85

from robo_comp.errors import AuthError, ConnectionLostError, FieldError, RateLimitError, RoboCompError
from robo_comp.teams.tokens import ORGANISER, REFEREE, check_team_name

log = logging.getLogger("robo_comp.protocol.curve")

#: The folder under the state folder that holds the key files.
KEYS_DIR = "keys"
#: The base name of the core's own certificate files.
CORE_NAME = "core"
#: Environment variables read when ``--curve-cert`` / ``--core-key`` are not given.
ENV_CERT = "ROBO_COMP_CURVE_CERT"
ENV_CORE_KEY = "ROBO_COMP_CORE_KEY"
#: The well-known endpoint of a ZAP handler (RFC 27), per ZeroMQ context.
ZAP_ENDPOINT = "inproc://zeromq.zap.01"
#: The ZAP domain of the core's server sockets.
ZAP_DOMAIN = b"robo_comp"
#: The PLAIN user name every client presents (the password is its token).
PLAIN_USER = b"robo_comp"
#: ZAP status (RFC 27) of a handshake without a valid credential; the client's monitor reports it
#: as HANDSHAKE_FAILED_AUTH with this value.
ZAP_REFUSED = 400
#: ZAP status of a valid credential the core cannot take now (its connection limits: full, or the
#: principal holds its share). libzmq closes a 300 silently, so the client could not say why; a 500
#: reaches it as HANDSHAKE_FAILED_AUTH with this value, and the client says what happened.
ZAP_NO_ROOM = 500
K = TypeVar("K")


@dataclass(frozen=True, slots=True)
class ClientKeys:
    """What a CURVE client socket needs: its own key pair and the core's public key (all z85)."""

    public: bytes
    secret: bytes
    server_public: bytes


@dataclass(frozen=True, slots=True)
class ServerKeys:
    """The core's key pair and the allow list: public key (z85) -> who owns it (team or ``referee``)."""

    public: bytes
    secret: bytes
    allowed: dict[bytes, str] = field(default_factory=dict)


# ---------------------------------------------------------------------- socket set-up
def secure_client(sock: zmq.Socket, keys: ClientKeys | None) -> None:
    """Make ``sock`` a CURVE client of the core before it connects; plain TCP when ``keys`` is None."""
    if keys is None:
        return
    sock.curve_secretkey = keys.secret
    sock.curve_publickey = keys.public
    sock.curve_serverkey = keys.server_public


def secure_server(sock: zmq.Socket, keys: ServerKeys | None) -> None:
    """Make ``sock`` a CURVE server before it binds (its handshakes go to the ZAP handler);
    plain TCP when ``keys`` is None."""
    if keys is None:
        return
    sock.curve_server = True
    sock.curve_publickey = keys.public
    sock.curve_secretkey = keys.secret
    sock.zap_domain = ZAP_DOMAIN


def open_server(sock: zmq.Socket, public: bytes, secret: bytes) -> None:
    """Make ``sock`` a CURVE server under a key pair with no allow list (no ZAP): any client may
    connect, and every client knows it talks to the holder of ``secret`` (the overhead camera's
    PUB socket, whose subscribers pin its public key)."""
    sock.curve_server = True
    sock.curve_publickey = public
    sock.curve_secretkey = secret


def secure_plain_client(sock: zmq.Socket, token: str | None) -> None:
    """Present ``token`` as the PLAIN password of ``sock`` before it connects (a core without
    ``--curve`` lets a connection in only with a valid token); nothing when ``token`` is None."""
    if token is None:
        return
    sock.plain_username = PLAIN_USER
    sock.plain_password = token.strip().encode("utf-8", "surrogatepass")


#: The socket-monitor events that tell a client how its handshake with the core ended.
HANDSHAKE_EVENTS = (zmq.EVENT_HANDSHAKE_SUCCEEDED | zmq.EVENT_HANDSHAKE_FAILED_AUTH
                    | zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL | zmq.EVENT_HANDSHAKE_FAILED_NO_DETAIL)


def handshake_error(frames: list[bytes], curve: bool) -> RoboCompError | None:
    """What a client tells its user about one monitor message (see :data:`HANDSHAKE_EVENTS`):
    None when the handshake succeeded (or the event says nothing about it), else the error."""
    event = zmq.utils.monitor.parse_monitor_message(frames)
    if event["event"] == zmq.EVENT_HANDSHAKE_FAILED_AUTH:
        if event["value"] == ZAP_NO_ROOM:
            return RateLimitError("the core accepts this token or key but has no room for another connection "
                                  "now: it is full (the last connections are kept for the referee and the organiser's "
                                  "hosts), or your team holds its share of sessions (close the clients you do "
                                  "not use); try again later")
        if curve:
            return AuthError("the core refused this connection's CurveZMQ key: use the secret certificate "
                             "the organiser gave you (--curve-cert) and this core's core.key (--core-key)")
        return AuthError("the core refused this connection: the token is not valid for this core; use the "
                         "token file the organiser gave you")
    if event["event"] in (zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL, zmq.EVENT_HANDSHAKE_FAILED_NO_DETAIL):
        hint = ("it may not run with --curve (leave out --curve-cert and --core-key)" if curve else
                "if it runs with --curve, give --curve-cert and --core-key")
        return ConnectionLostError(f"the connection to the core failed during its handshake: {hint}")
    return None


def secure_plain_server(sock: zmq.Socket) -> None:
    """Make ``sock`` a PLAIN server before it binds: its handshakes go to the ZAP handler, which
    lets in only a valid token (see :class:`ZapHandler`)."""
    sock.plain_server = True
    sock.zap_domain = ZAP_DOMAIN


@dataclass(slots=True)
class Tally:
    """Connections refused or cut for one peer since the last beat: how many, and the last reason
    (the core logs them in bulk: :meth:`ZapHandler.take_refused`, ``ConnectionGuard.take_cut``)."""

    count: int = 0
    reason: str = ""


class Tallies(dict[K, Tally]):
    """:class:`Tally` rows per peer, counted until :meth:`take` hands them over."""

    def add(self, key: K, reason: str) -> None:
        """Count one more refusal or cut of ``key``."""
        row = self.setdefault(key, Tally())
        row.count += 1
        row.reason = reason

    def take(self) -> dict[K, Tally]:
        """The rows so far, and start counting anew."""
        rows = dict(self)
        self.clear()
        return rows


class ZapHandler:
    """The core's ZAP handler: a REP socket on :data:`ZAP_ENDPOINT`, served from the core's poller.

    Under CurveZMQ it lets a handshake through when the client's public key is in ``allowed``;
    with PLAIN (every core without ``--curve``) when the password is a token ``lookup`` accepts
    (the core's :meth:`robo_comp.teams.tokens.TokenBook.lookup`, so every kind of principal it
    knows is accepted). The ZAP reply's user id (each message's ``User-Id`` property) names who
    proved themselves: the key's owner, or ``role:name`` of the token's principal
    (:attr:`principals` maps it back).

    Bind it before the server sockets and close it after them: while no handler is bound,
    libzmq would let every client in.
    """

    def __init__(self, ctx: zmq.Context, allowed: dict[bytes, str] | None = None,
                 lookup: Callable[[str], Any] | None = None,
                 admit: Callable[[Any], str | None] | None = None) -> None:
        self.allowed = dict(allowed or {})
        self.lookup = lookup
        #: Asked about every principal that proved itself: None lets it in, a sentence refuses it
        #: (the core's connection limits).
        self.admit = admit
        #: User id -> principal, for PLAIN handshakes.
        self.principals: dict[str, Any] = {}
        self.sock = ctx.socket(zmq.REP)
        self.sock.setsockopt(zmq.LINGER, 0)
        try:
            self.sock.bind(ZAP_ENDPOINT)
        except zmq.ZMQError as e:
            self.sock.close(0)
            raise FieldError(f"cannot start the transport's credential check in this process: {e}") from None
        self.accepted = 0
        self.refused = 0
        self._tally: Tallies[tuple[str, str]] = Tallies()

    def serve(self) -> int:
        """Answer every waiting ZAP request without blocking; return how many were answered."""
        n = 0
        while True:
            try:
                frames = self.sock.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return n
            n += 1
            self.sock.send_multipart(self._answer(frames))

    def _answer(self, frames: list[bytes]) -> list[bytes]:
        """The reply to one ZAP request (RFC 27): 200 for an allowed CURVE key or a valid PLAIN
        token, 400 otherwise."""
        if len(frames) < 6:
            return [b"1.0", b"", b"500", b"malformed ZAP request", b"", b""]
        version, request_id, _domain, address, _identity, mechanism, *creds = frames
        if version != b"1.0":
            return [b"1.0", request_id, b"500", b"unknown ZAP version", b"", b""]
        who: str | None = None
        principal: Any = None
        why = "no valid credential"
        if mechanism == b"CURVE" and len(creds) == 1:
            who = self.allowed.get(z85.encode(creds[0]))
            principal = who
            why = "the key is not in STATE/keys"
        elif mechanism == b"PLAIN" and len(creds) == 2 and self.lookup is not None:
            try:
                principal = self.lookup(creds[1].decode("utf-8", "surrogateescape"))
            except RoboCompError:
                why = "the password is not a valid token"
            else:
                who = f"{principal.role}:{principal.name}"
                self.principals[who] = principal
        status = ZAP_REFUSED
        if who is not None and self.admit is not None:
            full = self.admit(principal)
            if full is not None:
                who, why, status = None, full, ZAP_NO_ROOM
        if who is not None:
            self.accepted += 1
            return [b"1.0", request_id, b"200", b"OK", who.encode(), b""]
        self.refused += 1
        self._tally.add((mechanism.decode(errors="replace"), address.decode(errors="replace")), why)
        return [b"1.0", request_id, str(status).encode(), why.encode()[:200], b"", b""]

    @property
    def refusals_waiting(self) -> bool:
        """Whether handshakes were refused since the last :meth:`take_refused`."""
        return bool(self._tally)

    def take_refused(self) -> dict[tuple[str, str], Tally]:
        """The refusals since the last call, per (mechanism, peer address), and start counting anew
        (the core logs them once a beat: a flood of bad handshakes never floods the log)."""
        return self._tally.take()

    def close(self) -> None:
        """Close the ZAP socket (after the server sockets)."""
        self.sock.close(0)


# ---------------------------------------------------------------------- key files
def keys_dir(state: str | Path) -> Path:
    """``STATE/keys``."""
    return Path(state) / KEYS_DIR


def _load(path: Path, what: str) -> tuple[bytes, bytes | None]:
    try:
        public, secret = zmq.auth.load_certificate(path)
    except (OSError, ValueError) as e:
        raise FieldError(f"cannot read the CurveZMQ {what} {path}: {e}") from None
    return public, secret


def load_public(path: str | Path) -> bytes:
    """The public key (z85) in a certificate file (``.key`` or ``.key_secret``)."""
    return _load(Path(path), "certificate")[0]


def load_secret(path: str | Path) -> tuple[bytes, bytes]:
    """``(public, secret)`` (z85) from a secret certificate file (``NAME.key_secret``)."""
    public, secret = _load(Path(path), "secret certificate")
    if not secret:
        raise FieldError(f"{path} holds only a public key; give the secret certificate "
                         "(the NAME.key_secret file the organiser handed you)")
    return public, secret


def _create(kdir: Path, name: str) -> bool:
    """Create ``name.key`` and ``name.key_secret`` (0600) unless the secret exists; True if created."""
    secret = kdir / f"{name}.key_secret"
    public = kdir / f"{name}.key"
    if secret.is_file():
        if not public.is_file():  # the public half went missing: write it again from the secret one
            pub, _ = load_secret(secret)
            public.write_text(f"#   ZeroMQ CURVE Public Certificate of {name}\n\nmetadata\ncurve\n"
                              f"    public-key = \"{pub.decode()}\"\n")
        os.chmod(secret, 0o600)
        return False
    tmp = Path(tempfile.mkdtemp(dir=kdir))  # 0700: the secret is never readable by others, not even briefly
    try:
        tmp_pub, tmp_sec = (Path(p) for p in zmq.auth.create_certificates(tmp, name))
        os.chmod(tmp_sec, 0o600)
        os.chmod(tmp_pub, 0o644)
        os.replace(tmp_sec, secret)
        os.replace(tmp_pub, public)
    finally:
        for p in tmp.iterdir():
            p.unlink()
        tmp.rmdir()
    return True


def create_keys(state: str | Path, teams: list[str]) -> dict[str, bool]:
    """Create the core's, each team's, the referee's and the organiser's (robot hosts, camera) key
    pairs in ``STATE/keys``.

    Existing key pairs are kept (running it again only adds what is missing). Returns
    name -> True when that pair was created now.
    """
    names = [CORE_NAME, *(check_team_name(t) for t in teams), REFEREE, ORGANISER]
    kdir = keys_dir(state)
    kdir.mkdir(parents=True, exist_ok=True)
    os.chmod(kdir, 0o700)
    return {name: _create(kdir, name) for name in names}


def load_server_keys(state: str | Path, teams: list[str]) -> ServerKeys:
    """The core's key pair and the allow list (every ``*.key`` in ``STATE/keys`` but the core's).

    Raises :class:`FieldError` when the keys are missing, or a team of this core has none.
    """
    kdir = keys_dir(state)
    core_secret = kdir / f"{CORE_NAME}.key_secret"
    if not core_secret.is_file():
        raise FieldError(f"--curve needs the core's keys in {kdir}: "
                         f"run robo-comp keys --state {state} first")
    public, secret = load_secret(core_secret)
    allowed: dict[bytes, str] = {}
    for path in sorted(kdir.glob("*.key")):
        if path.stem != CORE_NAME:
            allowed[load_public(path)] = path.stem
    missing = [n for n in [*teams, REFEREE, ORGANISER] if n not in allowed.values()]
    if missing:
        raise FieldError(f"no CurveZMQ key for {', '.join(missing)} in {kdir}: "
                         f"run robo-comp keys --state {state} --teams {','.join(teams)} first")
    return ServerKeys(public, secret, allowed)


# ---------------------------------------------------------------------- the client side
def _state_info(core: str) -> tuple[Path, dict[str, object]] | None:
    """``(state folder, core.json)`` when ``core`` names a state folder or its core.json."""
    if "://" in core:
        return None
    path = Path(core)
    if path.is_dir():
        path = path / "core.json"
    try:
        info = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return (path.parent, info) if isinstance(info, dict) else None


def _token_owner(state: Path, token: str | None) -> str | None:
    """Whose key goes with token ``token`` in the state folder: a team name, ``referee``,
    ``organiser`` (a robot host's token) or None."""
    if not token:
        return None
    token = token.strip()
    for path in [state / "referee.token", *sorted((state / "teams").glob("*.token")),
                 *sorted((state / "hosts").glob("*.token"))]:
        try:
            if path.read_text().strip() == token:
                if path.parent.name == "hosts":
                    return ORGANISER
                return REFEREE if path.name == "referee.token" else path.stem
        except OSError:
            continue
    return None


def client_keys(core: str, token: str | None = None, cert: str | Path | None = None,
                core_key: str | Path | None = None) -> ClientKeys | None:
    """The CURVE keys a client of ``core`` uses, or None for plain TCP.

    ``cert`` (the client's secret certificate) and ``core_key`` (the core's public certificate)
    come from the options, else from ``$ROBO_COMP_CURVE_CERT`` / ``$ROBO_COMP_CORE_KEY``. When
    ``core`` is a state folder whose ``core.json`` says ``"curve": true``, the core's key comes
    from there and the client's certificate defaults to ``STATE/keys/<owner of token>.key_secret``.
    """
    cert = cert or os.environ.get(ENV_CERT) or None
    core_key = core_key or os.environ.get(ENV_CORE_KEY) or None
    found = _state_info(core)
    wants = bool(found and found[1].get("curve"))
    if cert is None and core_key is None and not wants:
        return None
    if core_key is not None:
        server_public = load_public(core_key)
    elif found and isinstance(found[1].get("curve_public"), str):
        server_public = str(found[1]["curve_public"]).encode()
    else:
        raise FieldError("--curve-cert needs --core-key PATH too: the core's public certificate "
                         "(core.key, from the organiser)")
    if cert is None and found is not None:
        owner = _token_owner(found[0], token)
        guess = keys_dir(found[0]) / f"{owner}.key_secret" if owner else None
        if guess is not None and guess.is_file():
            cert = guess
    if cert is None:
        raise FieldError(f"the core at {core} uses CurveZMQ: give --curve-cert PATH, your secret "
                         "certificate (NAME.key_secret, from the organiser)")
    public, secret = load_secret(cert)
    return ClientKeys(public, secret, server_public)


def add_curve_args(p: argparse.ArgumentParser) -> None:
    """``--curve-cert`` and ``--core-key``, shared by every command that connects to a core."""
    p.add_argument("--curve-cert", metavar="PATH",
                   help=f"CurveZMQ: your secret certificate (NAME.key_secret from the organiser; "
                        f"default ${ENV_CERT}, or STATE/keys/<your team>.key_secret)")
    p.add_argument("--core-key", metavar="PATH",
                   help=f"CurveZMQ: the core's public certificate (core.key; default ${ENV_CORE_KEY}, "
                        "or the core's key in STATE/core.json)")


__all__ = ["HANDSHAKE_EVENTS", "ClientKeys", "ServerKeys", "Tallies", "Tally", "ZAP_NO_ROOM", "ZAP_REFUSED", "ZapHandler", "add_curve_args", "client_keys",
           "create_keys", "handshake_error", "load_server_keys", "open_server", "secure_client", "secure_plain_client",
           "secure_plain_server", "secure_server"]
