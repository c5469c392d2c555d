"""Team and referee tokens: created on first start, kept in the state folder (mode 0600)."""
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


@dataclass(frozen=True, slots=True)
class Principal:
    """Who is behind a token: a team, or the referee (``team`` is None)."""

    role: str  # "team" or "referee"
    team: str | None

    @property
    def name(self) -> str:
        """The team's name, or ``referee``."""
        return self.team or REFEREE


def check_team_name(name: str) -> str:
    """Return ``name`` if it is a valid team name, else raise :class:`FieldError`."""
    if not TEAM_NAME.match(name) or name == REFEREE:
        raise FieldError(
            f"team name {name!r} is not allowed: use 1-32 lower-case letters, digits, '-' or '_', "
            "starting with a letter (and not 'referee')")
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
    """Maps tokens to principals; tokens live in ``STATE/teams/<team>.token`` and ``STATE/referee.token``."""

    def __init__(self, state_dir: Path, teams: list[str]) -> None:
        self.teams = [check_team_name(t) for t in teams]
        self._by_token: dict[str, Principal] = {}
        for team in self.teams:
            self._by_token[_read_or_create(state_dir / "teams" / f"{team}.token")] = Principal("team", team)
        self.referee_token = _read_or_create(state_dir / "referee.token")
        self._by_token[self.referee_token] = Principal("referee", None)

    def token_of(self, team: str) -> str:
        """The token of ``team`` (for the demo and tests that run in the core's host)."""
        for tok, p in self._by_token.items():
            if p.team == team:
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
