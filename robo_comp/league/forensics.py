"""Crash forensics: what a match says when team code failed in it, and how to see it again.

A team's ``play`` that raised ends as a ``task.done`` whose result has ``reason: "error"``, the
line and the traceback through the team's files (the sandbox gives them). :func:`crashes` reads them from a
match's events (a league match's or an engine run's, :attr:`robo_comp.engine.bench.MatchRun.events`)
with the robot call the robot made last before it (the bench logs each answered call as
``robot.call``), and :func:`crash_text` says it to the student with one command that plays the
same match again on their machine (:func:`rerun_command`: ``robo-comp league rerun``). League
matches are deterministic (docs/league.md), so the command shows the same crash.
"""
from __future__ import annotations

import shlex
from dataclasses import asdict, dataclass, field
from typing import Any

#: Crash reports kept per team and match (the first ones; the same error on every robot counts once per robot).
MAX_PER_TEAM = 5


@dataclass
class Crash:
    """One failure of team code in a match."""

    team: str
    tag: int
    task: str
    message: str
    line: int | None
    t: float
    #: The robot call the robot made last before it failed (``robot.go_to(3, 4)``; "" when none),
    #: and what that call answered (``ok`` or the refusal).
    call: str = ""
    call_answer: str = ""
    traceback: list[str] = field(default_factory=list)

    def plain(self) -> dict[str, Any]:
        """As plain data (a match result keeps it)."""
        return asdict(self)


def _shown_call(ev: dict[str, Any]) -> tuple[str, str]:
    args = ", ".join(repr(a) for a in ev.get("args") or [])
    answer = "answered" if ev.get("ok") else f"refused: {str(ev.get('error', ''))[:200]}"
    return f"robot.{ev.get('name')}({args[:120]})", answer


def crashes(events: list[dict[str, Any]]) -> list[Crash]:
    """The failures of team code in a match's events (bench format: ``t``, ``topic``, ``team``
    and the data), in order, at most :data:`MAX_PER_TEAM` per team."""
    last_call: dict[int, dict[str, Any]] = {}
    out: list[Crash] = []
    per_team: dict[str, int] = {}
    for ev in events:
        topic = ev.get("topic")
        if topic == "robot.call" and isinstance(ev.get("tag"), int):
            last_call[ev["tag"]] = ev
        elif topic == "task.done" and not ev.get("ok"):
            result = ev.get("result")
            why: dict[str, Any] = result if isinstance(result, dict) else {}  # reason, line, traceback
            if why.get("reason") != "error":
                continue
            team = str(ev.get("team"))
            if per_team.get(team, 0) >= MAX_PER_TEAM:
                continue
            per_team[team] = per_team.get(team, 0) + 1
            call, answer = _shown_call(last_call[ev["tag"]]) if ev.get("tag") in last_call else ("", "")
            out.append(Crash(team, int(ev.get("tag") or 0), str(ev.get("name", "")), str(ev.get("status", "")),
                             why.get("line") if isinstance(why.get("line"), int) else None, float(ev.get("t", 0.0)),
                             call, answer, [str(x) for x in why.get("traceback") or []]))
    return out


def rerun_command(league: str, match: Any, team: str | None = None) -> str:
    """The command that plays league match ``match`` again here (with the team's own folder in
    place of its submission when ``team`` is given: edit, then run it again)."""
    cmd = f"robo-comp league rerun {shlex.quote(str(league))} {match}"
    return cmd + (f" --team {shlex.quote(team)}=PATH" if team else "")


def crash_text(c: dict[str, Any], *, seed: Any = None, scenario: Any = None, command: str | None = None) -> str:
    """A crash (:meth:`Crash.plain`) as the lines a student reads: who, when, where, why, how to see it again."""
    where = f"line {c['line']}" if c.get("line") else "no line of your files"
    lines = [f"{c['team']}: robot {c['tag']}'s {c['task']} failed at {c['t']:g} s of match time"
             + (f" (seed {seed}, scenario {scenario})" if seed is not None else "") + f", {where}: {c['message']}"]
    if c.get("call"):
        lines.append(f"  its last robot call: {c['call']} ({c.get('call_answer') or 'answered'})")
    if c.get("traceback"):
        lines.append("  traceback (your files, outermost first):")
        lines.extend(f"    {x}" for x in c["traceback"])
    if command:
        lines.append(f"  reproduce it: {command}")
    return "\n".join(lines)


__all__ = ["Crash", "MAX_PER_TEAM", "crash_text", "crashes", "rerun_command"]
