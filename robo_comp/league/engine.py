"""One league match: the entrants' code in the real sandbox, played by the bench's engine.

A league match is the official match engine (:class:`robo_comp.testing.bench.Bench`: the robot
host's call table, the core's find judge and scoring rules, the core's event names) run on a
simulated clock, so the same scenario, seed and code give the same scores and a byte-identical
event log. :func:`play_match` takes and returns plain data, so a process pool or a Ray worker
can run it anywhere.

The league's contract with a team's code: every robot runs the team's ``play`` task from the
start of the match, as ``play(robot, width, height, index, count)`` (the arena's size, the
robot's index in its team and the team's robot count). A ``play`` stopped by a bump is started
again, at most :data:`RESTARTS` times per robot, and one that raised at most :data:`RETRIES`
times; one that broke a sandbox limit (time, memory, output) or returned is done.
"""
from __future__ import annotations

import dataclasses
import hashlib
import time
from pathlib import Path
from typing import Any

from robo_comp.errors import FieldError

#: The task every robot of an entrant runs.
PLAY = "play"
#: How often a robot's ``play`` is started again after a bump stopped it.
RESTARTS = 20
#: How often a robot's ``play`` is started again after it raised an error.
RETRIES = 3
#: The colours the entrants get, in slot order.
COLOURS = ("#e6194b", "#4363d8", "#3cb44b", "#f58231", "#911eb4", "#42d4f4", "#f032e6", "#bfef45")


def load_match_scenario(spec: str) -> Any:
    """The scenario of a match: a bundled name (``office``), a file path, or
    ``generated:SEED[:DIFFICULTY[:TEAMS]]`` (a procedurally generated one)."""
    from robo_comp.testing.match import resolve_scenario
    from robo_comp.world.scenario import load_scenario, parse_scenario

    if spec.startswith("generated:"):
        from robo_comp.world.generate import generate_scenario

        parts = spec.split(":")[1:]
        try:
            seed = int(parts[0])
            difficulty = float(parts[1]) if len(parts) > 1 else 0.5
            teams = int(parts[2]) if len(parts) > 2 else 2
        except (ValueError, IndexError):
            raise FieldError(f"scenario {spec!r}: write generated:SEED[:DIFFICULTY[:TEAMS]], "
                             "e.g. generated:7:0.5") from None
        return parse_scenario(generate_scenario(seed, difficulty=difficulty, teams=teams), spec)
    return load_scenario(resolve_scenario(spec))


def match_scenario(scenario: Any, teams: list[str], robots: int, seconds: float) -> Any:
    """``scenario`` with its first team slots renamed to the entrants (and ``robots`` each)."""
    slots = scenario.teams
    if len(slots) < len(teams):
        raise FieldError(f"scenario {scenario.name!r} has start zones for {len(slots)} teams, "
                         f"not the {len(teams)} of this match")
    placed = [dataclasses.replace(slot, name=name, colour=COLOURS[i % len(COLOURS)], robots=robots)
              for i, (slot, name) in enumerate(zip(slots, teams))]
    return dataclasses.replace(scenario, teams=placed, duration=float(seconds))


def play_match(spec: dict[str, Any]) -> dict[str, Any]:
    """Play one match and write its event log; return its result (plain data).

    ``spec``: ``id``, ``scenario`` (see :func:`load_match_scenario`), ``seed``, ``seconds``,
    ``robots`` (per team), ``entrants`` (``[{"team", "version", "files": {name: source}}]``)
    and ``log`` (where the core-format event log goes; None: not written).

    The result: ``id``, ``scores`` (team → score), ``ranks`` (team → 1 for the best; equal
    scores share a rank), ``victims`` (team → victims confirmed), ``bumps`` (team → count),
    ``sim_seconds``, ``wall_seconds``, ``events``, ``log`` and ``digest`` (SHA-256 of the log).
    """
    from robo_comp.testing.bench import Bench

    t0 = time.perf_counter()
    teams = [e["team"] for e in spec["entrants"]]
    if len(set(teams)) != len(teams):
        raise FieldError(f"match {spec.get('id')}: a team cannot play itself ({', '.join(teams)})")
    robots = int(spec.get("robots", 4))
    scenario = match_scenario(load_match_scenario(str(spec["scenario"])), teams, robots,
                              float(spec.get("seconds", 300)))
    with Bench(scenario, teams={t: robots for t in teams}, seed=int(spec.get("seed", 0)),
               max_sim_seconds=scenario.duration) as bench:
        for entrant in spec["entrants"]:
            for name, source in sorted(entrant["files"].items()):
                bench.load(name, source, team=entrant["team"])
        width, height = scenario.width, scenario.height
        plan = {}
        for team in teams:
            tags = bench.tags_of[team]
            for i, tag in enumerate(tags):
                plan[tag] = [(PLAY, [width, height, i, len(tags)])]
        restarts: dict[tuple[int, str], int] = {}

        def again(tag: int, outcome: dict[str, Any]) -> list[tuple[str, list[Any]]]:
            why = outcome.get("reason")
            if outcome["ok"] or outcome.get("start_error") or why not in ("stopped", "error"):
                return []  # done, or a broken limit (the sandbox said which)
            n = restarts.get((tag, why), 0)
            if n >= (RESTARTS if why == "stopped" else RETRIES):
                return []
            restarts[(tag, why)] = n + 1
            return [(PLAY, list(plan[tag][0][1]))]

        out = bench.run_match(plan, seconds=scenario.duration, on_done=again,
                              timeout=float(spec.get("timeout", 600)))
        digest = None
        log = spec.get("log")
        if log:
            path = bench.write_log(Path(log))
            digest = hashlib.sha256(path.read_bytes()).hexdigest()
        victims = {t: sorted(bench.board.found.get(t, set())) for t in teams}
        bumps = {t: sum(1 for e in out.events if e["topic"] == "robot.bump" and e["team"] == t) for t in teams}
        scores = {t: float(s) for t, s in out.scores.items()}
    return {"id": spec.get("id"), "scores": scores, "ranks": ranks_of(scores), "victims": victims,
            "bumps": bumps, "sim_seconds": out.sim_seconds, "wall_seconds": round(time.perf_counter() - t0, 4),
            "events": len(out.events), "log": str(log) if log else None, "digest": digest}


def ranks_of(scores: dict[str, float]) -> dict[str, int]:
    """Competition ranks from scores: 1 for the best, equal scores share a rank (1, 1, 3)."""
    ordered = sorted(scores.values(), reverse=True)
    return {t: 1 + ordered.index(s) for t, s in scores.items()}


__all__ = ["COLOURS", "PLAY", "RESTARTS", "RETRIES", "load_match_scenario", "match_scenario", "play_match", "ranks_of"]
