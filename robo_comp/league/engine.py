"""One league match: the entrants' code in the real sandbox, played by the bench's engine.

A league match is the official match engine (:class:`robo_comp.engine.bench.Bench`: the robot
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
from robo_comp.league.forensics import crashes

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
    from robo_comp.world.scenario import resolve_scenario
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


#: A league match's limits per entrant (see :class:`robo_comp.engine.budget.Budget`): events
#: and log bytes per robot per simulated second, CPU seconds of its code, real seconds the
#: match may wait for its code (a backstop: real time grows with the machine's load) and
#: memory (its sandbox's and the worker's growth for it) per match. A normal entrant uses a
#: fifth of them or less (the reference frontier team: 6 events and 1 KiB per robot-second, a
#: few CPU seconds); going over ends the match as the entrant's forfeit.
EVENTS_PER_ROBOT_SECOND = 25
LOG_BYTES_PER_ROBOT_SECOND = 4096
CPU_SECONDS = 120.0
WALL_SECONDS = 480.0
MEMORY_MIB = 512.0


def league_budget(robots: int, seconds: float, spec: dict[str, Any] | None = None) -> Any:
    """The budget of a league match of ``robots`` robots a team and ``seconds`` simulated
    seconds; ``spec["limits"]`` may override any field (for tests and organisers)."""
    from robo_comp.engine.budget import Budget

    scale = max(1, robots) * max(1.0, seconds)
    fields: dict[str, Any] = {"events": int(EVENTS_PER_ROBOT_SECOND * scale), "log_bytes": int(LOG_BYTES_PER_ROBOT_SECOND * scale),
              "cpu_seconds": CPU_SECONDS, "wall_seconds": WALL_SECONDS, "memory_mib": MEMORY_MIB}
    fields.update((spec or {}).get("limits") or {})
    return Budget(**fields)


def play_match(spec: dict[str, Any]) -> dict[str, Any]:
    """Play one match and write its event log; return its result (plain data).

    ``spec``: ``id``, ``scenario`` (see :func:`load_match_scenario`), ``seed``, ``seconds``,
    ``robots`` (per team), ``entrants`` (``[{"team", "version", "files": {name: source}}]``),
    ``debug_replay`` (who sees team code's debug drawing in the replay: ``team``, the default,
    or ``everyone``), ``rules`` (a scoring rules plugin ``MODULE:OBJECT``, as ``core --rules``;
    None: the installed rules) and ``log`` (where the core-format event log goes; None: not written).

    The result: ``id``, ``scores`` (team → score), ``ranks`` (team → 1 for the best; equal
    scores share a rank), ``victims`` (team → victims confirmed), ``bumps`` (team → count),
    ``sim_seconds``, ``wall_seconds``, ``cpu_seconds`` (the CPU time the match cost: this process's
    and its entrants' sandbox processes'; the same whatever the machine's load), ``events``, ``log``
    and ``digest`` (SHA-256 of the log),
    ``crashes`` (where team code raised: robot, task, last robot call, line, traceback, match
    time; :func:`robo_comp.league.forensics.crashes`), ``forfeit`` (None, or ``{"team", "limit", "message"}``: the entrant that went over a
    match limit; it ranks last whatever its score, the others rank by score) and ``limits``
    (team → what its code ran into: sandbox limits that stopped a robot, calls the call
    budget held back, and its use of the match limits), for the student's match report.
    """
    from robo_comp.engine.bench import Bench

    t0 = time.perf_counter()
    cpu0 = _process_cpu()
    teams = [e["team"] for e in spec["entrants"]]
    if len(set(teams)) != len(teams):
        raise FieldError(f"match {spec.get('id')}: a team cannot play itself ({', '.join(teams)})")
    robots = int(spec.get("robots", 4))
    scenario = match_scenario(load_match_scenario(str(spec["scenario"])), teams, robots,
                              float(spec.get("seconds", 300)))
    budget = league_budget(robots, scenario.duration, spec)
    pm = None
    if spec.get("rules"):  # the league's scoring rules plugin, as core --rules
        from robo_comp.plugins.manager import load_rules

        pm = load_rules(str(spec["rules"]))
    with Bench(scenario, teams={t: robots for t in teams}, seed=int(spec.get("seed", 0)), pm=pm,
               max_sim_seconds=scenario.duration, budget=budget, practice=False) as bench:
        bench.debug_replay = debug_replay(spec.get("debug_replay"))  # recorded in the log's core.started
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
            result = outcome.get("result")
            why = result.get("reason") if isinstance(result, dict) else None
            if outcome["ok"] or outcome.get("refused") or why not in ("bumped", "error"):
                return []  # done, or a broken limit (the sandbox said which)
            n = restarts.get((tag, why), 0)
            if n >= (RESTARTS if why == "bumped" else RETRIES):
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
        forfeit: dict[str, Any] | None = None if bench.forfeit is None else {"team": bench.forfeit.team, "limit": bench.forfeit.limit,
                                                      "message": bench.forfeit.message, "t": bench.forfeit.t}
        limits = {t: limits_hit(out.events, t, bench.used.get(t, {}), budget) for t in teams}
        crashed = [c.plain() for c in crashes(out.events)]
        sandbox_cpu = sum(sb.cpu_seconds() for sb in bench.sandboxes.values())
    return {"id": spec.get("id"), "scores": scores, "ranks": ranks_of(scores, forfeit["team"] if forfeit else None),
            "victims": victims, "bumps": bumps, "sim_seconds": out.sim_seconds,
            "wall_seconds": round(time.perf_counter() - t0, 4), "events": len(out.events),
            "cpu_seconds": round(_process_cpu() - cpu0 + sandbox_cpu, 4),
            "log": str(log) if log else None, "digest": digest, "forfeit": forfeit, "limits": limits,
            "crashes": crashed}


def _process_cpu() -> float:
    """CPU seconds (user and system) this process has used so far."""
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def debug_replay(value: Any) -> str:
    """A match's ``debug_replay`` choice, checked (``team`` when not given)."""
    from robo_comp.protocol.topics import DEBUG_REPLAY

    if value in (None, ""):
        return "team"
    if value not in DEBUG_REPLAY:
        raise FieldError(f"debug_replay must be one of {', '.join(DEBUG_REPLAY)}, not {value!r}")
    return str(value)


def limits_hit(events: list[dict[str, Any]], team: str, used: dict[str, float], budget: Any) -> dict[str, Any]:
    """What ``team``'s code ran into in a match: ``sandbox`` (the messages of the sandbox
    limits that stopped one of its robots' ``play``: time, memory, output), ``held_calls``
    (calls the call budget answered later) and ``use`` (its share of each match limit, 0..1;
    the CPU, real-time and memory shares are not deterministic and so not in the result)."""
    stopped = sorted({str(e.get("status")) for e in events
                      if e["topic"] == "task.done" and e["team"] == team and isinstance(e.get("result"), dict)
                      and e["result"].get("reason") == "limit"})
    use = {}
    for name in ("events", "log_bytes"):
        cap = getattr(budget, name)
        if cap:
            use[name] = round(used.get(name, 0.0) / cap, 3)
    return {"sandbox": stopped, "held_calls": int(used.get("held_calls", 0)), "use": use}


def ranks_of(scores: dict[str, float], forfeit: str | None = None) -> dict[str, int]:
    """Competition ranks from scores: 1 for the best, equal scores share a rank (1, 1, 3).
    A team that forfeited ranks last, alone, whatever its score; the others rank by score."""
    rest = {t: s for t, s in scores.items() if t != forfeit}
    ordered = sorted(rest.values(), reverse=True)
    ranks = {t: 1 + ordered.index(s) for t, s in rest.items()}
    if forfeit is not None and forfeit in scores:
        ranks[forfeit] = len(scores)
    return ranks


__all__ = ["COLOURS", "CPU_SECONDS", "EVENTS_PER_ROBOT_SECOND", "LOG_BYTES_PER_ROBOT_SECOND", "MEMORY_MIB", "PLAY",
           "RESTARTS", "RETRIES", "WALL_SECONDS", "debug_replay", "league_budget", "limits_hit", "load_match_scenario",
           "match_scenario", "play_match", "ranks_of"]
