"""Tokens: created on first start, kept in the state folder (mode 0600).

Three kinds of principal hold them:

* a **team** (``STATE/teams/<team>.token``): gives its robots commands, uploads code, reads its own
  robots. It never speaks for the world;
* the **referee** (``STATE/referee.token``): runs the match and sees everything;
* the organiser's **robot hosts** (``STATE/hosts/<team>.token``): the processes that run a team's
  robots (the simulation, a real robot's driver). Only they may register robots and report what
  happens to them (poses, pictures, bumps, task results). They stay on the organiser's machines;
  a team never gets one.
"""
from __future__ import annotations

import hmac
import os
import re
import secrets
from dataclasses import dataclass
from pathlib import Path

from robo_comp.errors import AuthError, FieldError

TEAM_NAME = re.compile(r"^[a-z][a-z0-9_-]{0,31}$")
REFEREE = "referee"
#: The name of the organiser's own CurveZMQ key (robot hosts and the overhead camera use it).
ORGANISER = "organiser"
#: Names no team may take: the referee's, and the organiser's key.
RESERVED = frozenset({REFEREE, ORGANISER})


@dataclass(frozen=True, slots=True)
class Principal:
    """Who is behind a token: a team, the referee (``team`` is None), or the organiser's robot
    host for a team's robots (role ``host``)."""

    role: str  # "team", "referee" or "host"
    team: str | None

    @property
    def name(self) -> str:
        """The team's name, ``referee``, or ``host/<team>`` for a robot host."""
        if self.role == "host":
            return f"host/{self.team}"
        return self.team or REFEREE


def check_team_name(name: str) -> str:
    """Return ``name`` if it is a valid team name, else raise :class:`FieldError`."""
    if not TEAM_NAME.match(name) or name in RESERVED:
        raise FieldError(
            f"team name {name!r} is not allowed: use 1-32 lower-case letters, digits, '-' or '_', "
            "starting with a letter (and not 'referee' or 'organiser')")
    return name


def _read_or_create(path: Path) -> str:
    if path.exists():
        token = path.read_text().strip()
        if len(token) >= 16:
            return token
    token = secrets.token_urlsafe(24)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(token + "\n")
    os.chmod(path, 0o600)
    return token


class TokenBook:
    """Maps tokens to principals; tokens live in ``STATE/teams/<team>.token``,
    ``STATE/hosts/<team>.token`` (the organiser's robot hosts) and ``STATE/referee.token``."""

    def __init__(self, state_dir: Path, teams: list[str]) -> None:
        self.teams = [check_team_name(t) for t in teams]
        self._by_token: dict[str, Principal] = {}
        for team in self.teams:
            self._by_token[_read_or_create(state_dir / "teams" / f"{team}.token")] = Principal("team", team)
        hosts = state_dir / "hosts"
        hosts.mkdir(parents=True, exist_ok=True)
        os.chmod(hosts, 0o700)  # the organiser's credentials: not for the teams' eyes
        for team in self.teams:
            self._by_token[_read_or_create(hosts / f"{team}.token")] = Principal("host", team)
        self.referee_token = _read_or_create(state_dir / "referee.token")
        self._by_token[self.referee_token] = Principal("referee", None)

    def token_of(self, team: str, role: str = "team") -> str:
        """The token of ``team`` (``role="host"``: of its robot host), for the demo and tests
        that run in the core's machine."""
        for tok, p in self._by_token.items():
            if p.team == team and p.role == role:
                return tok
        raise KeyError(team)

    def lookup(self, token: str) -> Principal:
        """Return the principal behind ``token`` or raise :class:`AuthError`."""
        # compare with every token in constant time (a few tokens: cheap), never a dict lookup
        p = None
        for tok, who in self._by_token.items():
            if hmac.compare_digest(tok.encode(), token.encode("utf-8", "surrogatepass")):
                p = who
        if p is None:
            raise AuthError("that token is not valid for this core; use the token file the organiser gave you")
        return p
