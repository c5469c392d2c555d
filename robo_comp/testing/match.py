"""A real match for tests: a core process in a temporary state folder, robot hosts, clients.

:func:`start_match` starts one; :class:`Match` holds it. Helpers: :func:`wait_for`,
:func:`wait_robots`, :func:`next_event_where`, :func:`resolve_scenario`.
"""
from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from subprocess import Popen
from typing import Any

from robo_comp.client import Client
from robo_comp.launch import start_core, start_robots, stop_all
from robo_comp.world.scenario import DEFAULT_SCENARIO, resolve_scenario

HEARTBEAT = 0.2


# ---------------------------------------------------------------------- waiting helpers
def wait_for(pred: Callable[[], Any], timeout: float = 10.0, what: str = "condition") -> Any:
    """Poll ``pred`` every 50 ms until it returns a truthy value, and return that value.

    Raises AssertionError naming ``what`` after ``timeout`` seconds.
    """
    t_end = time.monotonic() + timeout
    while True:
        v = pred()
        if v:
            return v
        if time.monotonic() > t_end:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.05)


def wait_robots(client: Client, n: int, status: str = "connected", timeout: float = 30.0) -> list[dict[str, Any]]:
    """Wait until ``client`` sees at least ``n`` robots with ``status``; return those rows by tag."""
    def ready() -> list[dict[str, Any]] | None:
        rows = sorted((r for r in client.robots() if r["status"] == status), key=lambda r: r["tag"])
        return rows if len(rows) >= n else None
    return wait_for(ready, timeout, f"{n} {status} robots")


def next_event_where(client: Client, pred: Callable[[dict[str, Any]], bool],
                     timeout: float = 10.0) -> dict[str, Any]:
    """Read pushed events (after ``client.watch()``) until one satisfies ``pred``; return it.

    Events read before the match are consumed. Raises AssertionError after ``timeout`` s.
    """
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        ev = client.next_event(min(0.2, max(0.0, t_end - time.monotonic())))
        if ev is not None and pred(ev):
            return ev
    raise AssertionError(f"timed out after {timeout} s waiting for a matching event")


# ---------------------------------------------------------------------- a real match
@dataclass
class Match:
    """A real core process (and the robot hosts started for it) in ``state``.

    Built by :func:`start_match` or the ``robo_match`` fixture; :meth:`close` stops it all.
    """

    state: Path
    scenario: Path | None
    proc: Popen[bytes]
    procs: list[Popen[bytes]] = field(default_factory=list)
    clients: list[Client] = field(default_factory=list)

    def token(self, team: str) -> str:
        """A team's token (``"referee"`` for the referee's), as the core wrote it."""
        path = self.state / ("referee.token" if team == "referee" else f"teams/{team}.token")
        return path.read_text().strip()

    def token_file(self, team: str) -> Path:
        """The token file of ``team`` (what ``--token-file`` takes)."""
        return self.state / ("referee.token" if team == "referee" else f"teams/{team}.token")

    def host_token(self, team: str) -> str:
        """The organiser's robot-host token for ``team``'s robots (``STATE/hosts/<team>.token``)."""
        return self.host_token_file(team).read_text().strip()

    def host_token_file(self, team: str) -> Path:
        """The robot-host token file of ``team`` (what ``robo-comp robots --token-file`` takes)."""
        return self.state / "hosts" / f"{team}.token"

    @property
    def teams(self) -> list[str]:
        """The match's team names (from the token files)."""
        return sorted(p.stem for p in (self.state / "teams").glob("*.token"))

    def client(self, team: str, **kw: Any) -> Client:
        """A connected :class:`Client` for ``team`` or ``"referee"`` (closed at teardown)."""
        c = Client(str(self.state), self.token(team), **kw)
        self.clients.append(c)
        return c

    def referee(self) -> Client:
        """A client holding the referee's token."""
        return self.client("referee")

    def robots(self, team: str, count: int = 1, *extra: str, organiser: bool = True,
               speed: float | None = None) -> Popen[bytes]:
        """Start a ``robo-comp robots`` process with ``count`` robots of ``team``.

        ``organiser=True`` passes the scenario file (``--scenario``): the simulated camera then
        shows the hidden victims, as on the organiser's hosts in a match. ``speed`` is in
        cells per second (default: the scenario's). The output goes to ``robots-<team>.log``
        in the state folder.
        """
        args = list(extra)
        if organiser and self.scenario is not None:
            args += ["--scenario", str(self.scenario)]
        if speed is not None:
            args += ["--speed", str(speed)]
        p = start_robots(self.state, team, count, *args)
        self.procs.append(p)
        return p

    def start(self) -> dict[str, Any]:
        """Start the match as the referee (not needed in practice mode, where it runs already)."""
        return self.referee().request("match", action="start")

    def scores(self, team: str = "referee") -> dict[str, Any]:
        """The ``score`` reply: ``teams`` (ranked rows), ``lines`` (the caller's), the clock."""
        c = self._cached(team)
        return c.request("score")

    def score_of(self, team: str) -> float:
        """``team``'s current score."""
        rows = {r["team"]: r for r in self.scores()["teams"]}
        return float(rows[team]["score"])

    def logged_events(self, topic: str | None = None) -> list[dict[str, Any]]:
        """Events the core has written to ``events.log`` so far (optionally of one topic),
        as ``{seq, t, topic, team, data}`` dicts."""
        from robo_comp.protocol.logfile import read_log

        path = self.state / "events.log"
        if not path.exists():
            return []
        return [{"seq": r.seq, "t": r.t, "topic": r.topic, "team": r.team, "data": r.data}
                for r in read_log(path, strict=False) if topic is None or r.topic == topic]

    def log_tail(self, name: str = "core.log", chars: int = 3000) -> str:
        """The end of a process log in the state folder (for assertion messages)."""
        p = self.state / name
        return p.read_text(errors="replace")[-chars:] if p.exists() else ""

    def _cached(self, team: str) -> Client:
        for c in self.clients:
            if c.token == self.token(team) and c.sock is not None:
                return c
        return self.client(team)

    def close(self) -> None:
        """Close the clients and stop every process (robot hosts first)."""
        for c in self.clients:
            c.close()
        self.clients.clear()
        stop_all([self.proc, *self.procs])

    def __enter__(self) -> Match:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def start_match(state: Path, scenario: str | os.PathLike[str] | None = DEFAULT_SCENARIO, *,
                teams: Iterable[str] | None = None, practice: bool = True,
                heartbeat: float = HEARTBEAT, extra: Iterable[str] = ()) -> Match:
    """Start a real core process for ``scenario`` with its state in ``state``.

    ``scenario`` is a path or a bundled name (None: the core's built-in arena).
    ``practice=True`` means no phases: the match runs at once and never ends; with False the
    match waits in ``setup`` until :meth:`Match.start`.
    """
    args = ["--heartbeat", str(heartbeat)]
    path = resolve_scenario(scenario) if scenario is not None else None
    if path is not None:
        args += ["--scenario", str(path)]
    if teams:
        args += ["--teams", ",".join(teams)]
    if practice and path is not None:
        args.append("--practice")
    proc = start_core(state, *args, *extra)
    return Match(state, path, proc)


__all__ = ["DEFAULT_SCENARIO", "Match", "next_event_where", "resolve_scenario", "start_match", "wait_for",
           "wait_robots"]
