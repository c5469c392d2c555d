"""Fair play in the league (issue 26): a hostile entrant can neither re-roll nor sink a match.

Real sandboxes, real team code (tests/league_entrants/*.py), the league's own engine.
"""
from __future__ import annotations

import ast
import json
import random
from pathlib import Path

import pytest

from robo_comp.league import reference, season
from robo_comp.league.engine import play_match
from robo_comp.protocol.logfile import read_recording

ENTRANTS = Path(__file__).parent / "league_entrants"


def entrant(name: str) -> dict:
    """A match entrant: a reference team or a file of tests/league_entrants."""
    path = ENTRANTS / f"{name}.py"
    files = {"play.py": path.read_text() if path.exists() else reference.source(name)}
    return {"team": name.replace("_", "-"), "version": name, "files": files}


def spec(tmp_path: Path, a: str, b: str, *, log: str, seed: int = 5, seconds: float = 30,
         limits: dict | None = None) -> dict:
    s = {"id": 1, "scenario": "demo_room", "seed": seed, "seconds": seconds, "robots": 2,
         "entrants": [entrant(a), entrant(b)], "log": str(tmp_path / log)}
    if limits:
        s["limits"] = limits
    return s


def printed(log: Path, team: str) -> list[str]:
    """The text team ``team``'s robots printed, from a league match's event log."""
    return [r.data["text"] for r in read_recording(log)[0] if r.topic == "robot.log" and r.team == team]


def sources_seen(log: Path) -> dict:
    """What the entropy entrant's first robot got from each source (its first printed value of
    each), from a league match's event log."""
    seen: dict = {}
    for r in read_recording(log)[0]:
        if r.topic == "robot.log" and r.team == "entropy" and r.data.get("tag") == 101:
            for line in r.data["text"].splitlines():
                name, value = ast.literal_eval(line)
                seen.setdefault(name, value)
    return seen


def play_fresh(s: dict, **env: str) -> dict:
    """Play match ``s`` in a fresh Python process, as a league worker plays it (with ``env``
    added to its environment); its result."""
    import os
    import subprocess
    import sys

    code = ("import json, sys; from robo_comp.league.engine import play_match; "
            "print(json.dumps(play_match(json.loads(sys.stdin.read()))))")
    out = subprocess.run([sys.executable, "-c", code], input=json.dumps(s), capture_output=True, text=True,
                         timeout=300, env=dict(os.environ, **env))
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


# ------------------------------------------------------------------ determinism
def test_a_hostile_entrant_cannot_reroll_its_match(tmp_path):
    """The entrant steers by hash(), id(), every way of turning an object into text (repr,
    str, f-strings, %, error messages), the order of sets of functions, objects, methods,
    built-ins, classes and singletons, and random.seed(). Two plays in two fresh processes,
    with address-space randomisation left on in the sandbox children (ROBO_COMP_SANDBOX_ASLR=1):
    the same log to the byte. Before issue 26 three plays gave three different logs; with
    the f-strings and sets added, the code before this test gave two different logs even
    with randomisation off, and different ones in every play with it on."""
    runs = [play_fresh(spec(tmp_path, "entropy", "frontier", log=f"m{i}.log", seconds=10), ROBO_COMP_SANDBOX_ASLR="1")
            for i in range(2)]
    assert len({r["digest"] for r in runs}) == 1, [r["scores"] for r in runs]
    assert (tmp_path / "m0.log").read_bytes() == (tmp_path / "m1.log").read_bytes()
    seen = sources_seen(tmp_path / "m0.log")
    # what the entrant got: fixed hashes of text, numbers for objects, no addresses anywhere
    assert isinstance(seen["hash-str"], int) and seen["hash-str"] == seen["hash-bytes"]
    assert seen["id"].startswith("refused: id() is not available")
    assert isinstance(seen["hash-function"], int) and isinstance(seen["hash-object"], int)
    assert isinstance(seen["hash-instance"], int) and seen["hash-instance"] < 10_000
    assert seen["repr-function"].startswith("<function helper #") and seen["repr-object"] == "<object object>"
    assert "object #" in seen["str-instance"] and "object #" in seen["fstring-instance"]
    assert seen["fstring-function"] == seen["percent-function"] == seen["str-function"] == seen["repr-function"]
    assert seen["fstring-generator"].startswith("<generator object gen #")
    assert seen["fstring-builtin-method"] == "<built-in method append of list object>"
    assert sorted(seen["set-of-functions"]) == list(range(24))
    # random.seed() without a value goes back to the match seed (5), never to os.urandom
    assert seen["random-reseeded"] == random.Random(5).random()
    assert all("0x" not in line for line in printed(tmp_path / "m0.log", "entropy"))
    # the seed, not a constant, fixes the hash: another match seed gives other hashes
    other = play_match(spec(tmp_path, "entropy", "frontier", log="seed6.log", seed=6, seconds=10))
    seen6 = sources_seen(tmp_path / "seed6.log")
    assert seen6["hash-str"] != seen["hash-str"] and other["digest"] != runs[0]["digest"]
    assert seen6["random-reseeded"] == random.Random(6).random()


def test_sandbox_hash_seed_follows_the_seed_outside_the_league(tmp_path):
    """Every sandbox child (a robot host's too) has its string hashing fixed by its seed."""
    from robo_comp.engine.bench import Bench

    src = (ENTRANTS / "entropy.py").read_text().replace(
        "def play(robot, width, height, index, count):", "def probe(robot):\n    return hash('robo')\n\n\n"
        "def play(robot, width, height, index, count):").replace(
        '"tasks": {', '"tasks": {"probe": {"description": "hash", "args": []}, ')
    got = []
    for seed in (1, 1, 2):
        with Bench("demo_room", robots=1, seed=seed) as bench:
            bench.load("entropy.py", src)
            got.append(bench.run("probe"))
    assert got[0] == got[1] != got[2]


# ------------------------------------------------------------------ budgets and forfeits
def test_a_flooding_entrant_is_held_to_its_call_budget(tmp_path):
    """499 pictures between two moves: the call budget answers them at its pace, so the match
    log stays small and the opponent plays on; the report says the calls waited."""
    res = play_match(spec(tmp_path, "flood", "frontier", log="flood.log"))
    assert res["forfeit"] is None and res["sim_seconds"] == 30
    pictures = sum(1 for r in read_recording(tmp_path / "flood.log")[0] if r.topic == "picture" and r.team == "flood")
    # burst 100 calls, then 10 a simulated second; a picture costs 4: 2 robots x (25 + 30 x 2.5) = 200
    assert 0 < pictures <= 2 * (25 + 30 * 10 / 4) + 2
    assert res["limits"]["flood"]["held_calls"] > 0 and res["limits"]["frontier"]["held_calls"] == 0
    assert any("waited for the call budget" in n for n in season.match_notes(res))
    assert res["scores"]["frontier"] > 0


def test_an_entrant_over_the_event_limit_forfeits_and_only_it(tmp_path):
    res = play_match(spec(tmp_path, "flood", "frontier", log="cap.log", limits={"events": 150}))
    assert res["forfeit"]["team"] == "flood" and res["forfeit"]["limit"] == "events"
    assert res["ranks"] == {"flood": 2, "frontier": 1}
    assert res["sim_seconds"] < 30  # the match ended early
    notes = season.match_notes(res)
    assert notes and notes[0].startswith("team flood forfeits the match: its robots caused more than 150 events")
    last = read_recording(tmp_path / "cap.log")[0][-1]
    assert last.topic == "match.phase" and last.data["forfeit"]["team"] == "flood"
    # a forfeit is deterministic too: the same limit, the same log
    again = play_match(spec(tmp_path, "flood", "frontier", log="cap2.log", limits={"events": 150}))
    assert again["digest"] == res["digest"]


def test_a_forfeit_ranks_the_entrant_last_even_when_it_leads():
    from robo_comp.league.engine import ranks_of

    assert ranks_of({"a": 40, "b": 3}, forfeit="a") == {"a": 2, "b": 1}
    assert ranks_of({"a": 40, "b": 3, "c": 40}, forfeit="c") == {"a": 1, "b": 2, "c": 3}


def test_an_entrant_over_the_log_bytes_limit_forfeits(tmp_path):
    res = play_match(spec(tmp_path, "frontier", "flood", log="bytes.log", limits={"log_bytes": 20_000}))
    assert res["forfeit"]["team"] == "flood" and res["forfeit"]["limit"] == "log_bytes"
    assert res["ranks"]["frontier"] == 1


def test_an_entrant_that_computes_too_long_forfeits_on_cpu_time(tmp_path):
    """Computing before every turn (a third of a second, less where the CPU or the policy is faster):
    under the sandbox's 2 s slice, over the match's CPU limit for the entrant (here 3 s) long
    before the match's 120 s (at 30 s, as before, a faster lookup of ``math.sqrt`` in the sandbox
    left the entrant under 3 s when the match ended); the opponent is not charged for it."""
    res = play_match(spec(tmp_path, "slow", "frontier", log="slow.log", seconds=120, limits={"cpu_seconds": 3.0}))
    assert res["forfeit"] is not None, res
    assert res["forfeit"]["team"] == "slow" and res["forfeit"]["limit"] == "cpu_seconds"
    assert res["ranks"] == {"slow": 2, "frontier": 1}
    assert res["sim_seconds"] < 120  # the match ended at the forfeit


def test_a_loaded_machine_does_not_make_an_entrant_forfeit(tmp_path, monkeypatch):
    """The machine does not run frontier's sandbox for 1.2 s when its first robot starts (its
    process is stopped, as on a machine too busy to schedule it): real time passes, frontier's
    code costs nothing. The compute limit (0.8 s) charges CPU time, so the entrant that really
    computes (slow) forfeits, not frontier. On the code before, which charged the real time
    the match waited, frontier forfeited this match (a 0.8 s limit of real time)."""
    import os
    import signal
    import threading

    from robo_comp.sandbox.parent import Sandbox

    start_task = Sandbox.start_task
    stopped: list[int] = []

    def busy_machine(self, tag, task, args=()):
        if self.team == "frontier" and not stopped and self.pid:
            stopped.append(self.pid)
            os.kill(self.pid, signal.SIGSTOP)
            threading.Timer(1.2, os.kill, (self.pid, signal.SIGCONT)).start()
        return start_task(self, tag, task, args)

    monkeypatch.setattr(Sandbox, "start_task", busy_machine)
    res = play_match(spec(tmp_path, "frontier", "slow", log="busy.log", limits={"cpu_seconds": 0.8}))
    assert stopped  # frontier's sandbox was held up
    assert res["forfeit"]["team"] == "slow" and res["forfeit"]["limit"] == "cpu_seconds"
    assert res["ranks"] == {"frontier": 1, "slow": 2}


def test_an_entrant_that_grows_the_worker_past_the_memory_limit_forfeits(tmp_path):
    """Memory is charged to the entrant whose robots took it: hoard asks for the biggest map
    piece again and again (about 1.8 MB of log, 10 MiB of the worker's memory in 15 s), chatter
    radios long messages (2.9 MB of log, under 2 MiB of memory). With a 5 MiB limit hoard
    forfeits, whichever side it plays; the code before charged the worker's growth to the
    entrant that logged the most, and chatter forfeited both matches. Played in a fresh process,
    as a league worker plays a match (a long-lived test process reuses memory it freed)."""
    limits = {"memory_mib": 5, "events": 10**9, "log_bytes": 10**12}
    for a, b in (("hoard", "chatter"), ("chatter", "hoard")):
        res = play_fresh(spec(tmp_path, a, b, log=f"{a}.log", seconds=15, limits=limits))
        assert res["forfeit"]["team"] == "hoard" and res["forfeit"]["limit"] == "memory_mib", res["forfeit"]
        assert res["ranks"] == {"chatter": 1, "hoard": 2}
        assert "its robots took" in res["forfeit"]["message"]


def test_the_report_shows_the_forfeit_and_the_provisional_mark(tmp_path):
    from robo_comp.league.report import render_report, standings_text
    from robo_comp.league.store import LeagueStore

    with LeagueStore(tmp_path / "lg", create=True) as store:
        store.configure(scenarios=["demo_room"], robots=2, seconds=30)
        store.add_submission("flood", {"play.py": (ENTRANTS / "flood.py").read_text()}, "test")
        store.add_submission("frontier", {"play.py": reference.source("frontier")}, "test")
        ids = store.schedule("round-robin", 1, [["flood", "frontier"]])
        spec_ = dict(store.spec(ids[0]), limits={"events": 150})
        result = play_match(spec_)
        store.started(ids[0])
        store.finished(ids[0], result)
        season.rate_played(store)
        view = season.league_view(store)
    page = render_report(view)
    assert "team flood forfeits the match" in page
    text = standings_text(view)
    assert " ?" in text and "provisional" in text
    assert all(row["provisional"] for row in view["standings"])  # one match: nobody is sure yet
    assert json.dumps(view)  # still plain data


# ------------------------------------------------------------------ fair formats
def spreads(plan: list[tuple[list[str], int]], teams: list[str], scenarios: int) -> tuple[int, int]:
    """The largest difference, over the teams, between a team's most and least played scenario,
    and between its matches on the first and on the second side."""
    c = {t: [0] * scenarios for t in teams}
    d = {t: [0, 0] for t in teams}
    for group, k in plan:
        for i, t in enumerate(group):
            c[t][k] += 1
            d[t][i] += 1
    return max(max(v) - min(v) for v in c.values()), max(max(v) - min(v) for v in d.values())


@pytest.mark.parametrize("scenarios", [1, 2, 3, 4])
def test_a_round_robin_gives_every_team_every_scenario_and_side_evenly(scenarios):
    """4 to 32 teams: each team's matches per scenario differ by at most one, and its first and
    second sides by at most one. Where that is impossible (each team plays a multiple of the
    scenario count, and a scenario's matches would have to form a regular graph of odd degree
    on an odd number of teams), by two. Before issue 26 one team of 6 played all 5 of its
    matches on one scenario."""
    from robo_comp.league.schedule import balance, round_robin

    for n in range(4, 33):
        teams = [f"t{i:02d}" for i in range(n)]
        plan = balance([g for rnd in round_robin(teams) for g in rnd], scenarios)
        assert sorted(t for g, _ in plan for t in g) == sorted(teams * (n - 1))  # the same matches
        per = n - 1
        forced = per % scenarios == 0 and (n * (per // scenarios)) % 2 == 1
        scen, side = spreads(plan, teams, scenarios)
        assert scen <= (2 if forced else 1) and side <= 1, (n, scenarios, scen, side)


def test_swiss_rounds_rotate_the_scenarios_and_balance_sides(league_of_16):
    """A Swiss round plays one scenario, in turn, so whoever a team meets it plays the pool
    evenly; every team's sides stay at most one apart over the season (the league's own
    scheduling, through the store)."""
    store = league_of_16
    season.run_format(store, _NoPlay(winner=max), "swiss", rounds=4)
    season.run_format(store, _NoPlay(winner=max), "swiss", rounds=3)  # a second Swiss goes on from the first
    teams = sorted(store.newest())
    pool = store.settings()["scenarios"]
    plan = [(m.teams, pool.index(m.scenario)) for m in store.matches()]
    scen, side = spreads(plan, teams, len(pool))
    assert scen <= 1 and side <= 1
    assert {m.round: m.scenario for m in store.matches()} == {r: pool[(r - 1) % 2] for r in range(1, 8)}


@pytest.mark.parametrize("scenarios", [1, 2, 3, 4])
def test_a_swiss_season_keeps_every_teams_sides_even(scenarios):
    """4 to 32 teams, the default number of Swiss rounds (log2 of the count, rounded up), results
    drawn at random, five seasons each, scheduled as the store does (one scenario a round):
    every team's first and second sides differ by at most one over the season, and no pair
    meets twice. Before, sides were balanced per round only: 333 of these 580 seasons had a
    team two or three apart. Scenarios differ by at most one for a team, by two only for one
    whose bye fell on the only round of a scenario (which no schedule of one scenario a round
    avoids)."""
    from robo_comp.league.schedule import balance, side_lean, swiss_round

    for n in range(4, 33):
        for trial in range(5):
            rng = random.Random(f"{n}:{scenarios}:{trial}")
            teams = [f"t{i:02d}" for i in range(n)]
            strength = {t: rng.random() for t in teams}
            points = dict.fromkeys(teams, 0)
            played: list[frozenset[str]] = []
            byes: set[str] = set()
            plan: list[tuple[list[str], int]] = []
            prior: dict[str, list[int]] = {}
            sides: dict[str, list[int]] = {}
            use = [0] * scenarios
            for rnd in range((n - 1).bit_length()):
                standing = sorted(teams, key=lambda t: (-points[t], t))
                pairs = swiss_round(standing, played, byes, side_lean(g for g, _ in plan))
                played += [frozenset(p) for p in pairs]
                byes |= set(teams) - {t for p in pairs for t in p}
                for g, k in balance(pairs, scenarios, prior=prior, prior_sides=sides, prior_use=use,
                                    scenario=rnd % scenarios):
                    plan.append((g, k))
                    use[k] += 1
                    for i, t in enumerate(g):
                        prior.setdefault(t, [0] * scenarios)[k] += 1
                        sides.setdefault(t, [0, 0])[i] += 1
                    a, b = g
                    points[a if rng.random() < strength[a] / (strength[a] + strength[b]) else b] += 1
            assert len(set(played)) == len(played), (n, trial)
            assert max(abs(v) for v in side_lean(g for g, _ in plan).values()) <= 1, (n, trial, sides)
            for t, per in prior.items():
                assert max(per) - min(per) <= (2 if t in byes else 1), (n, trial, t, per)


class _NoPlay:
    """A runner that plays nothing: each match ends as a draw, or as a win of ``winner(teams)``
    (the schedule is what is tested)."""

    def __init__(self, winner=None):
        self.winner = winner

    def run(self, specs, on_result, on_error):
        for s in specs:
            teams = [e["team"] for e in s["entrants"]]
            won = self.winner(teams) if self.winner else None
            on_result(s, {"id": s["id"], "scores": {t: float(t == won) for t in teams},
                          "ranks": {t: 1 if won in (None, t) else 2 for t in teams}, "wall_seconds": 0.0})


@pytest.fixture
def league_of_16(tmp_path):
    from robo_comp.league.store import LeagueStore

    with LeagueStore(tmp_path / "lg", create=True) as store:
        store.configure(scenarios=["demo_room", "office"], robots=2, seconds=30)
        season.submit_reference(store, 16)
        yield store


# ------------------------------------------------------------------ ratings that say how sure they are
def test_the_order_free_rerating_does_not_depend_on_match_order():

    from robo_comp.league.ratings import bradley_terry, kendall_tau

    rng = random.Random(3)
    truth = [f"t{i}" for i in range(8)]
    matches = []
    for _ in range(300):
        a, b = rng.sample(range(8), 2)
        p_a = 1 / (1 + 3 ** ((a - b) / 2))  # the lower index is stronger
        matches.append({truth[a]: 1, truth[b]: 2} if rng.random() < p_a else {truth[a]: 2, truth[b]: 1})
    one = bradley_terry(matches)
    shuffled = matches[:]
    rng.shuffle(shuffled)
    again = bradley_terry(shuffled)
    assert all(again[t] == pytest.approx(one[t]) for t in truth)
    order = sorted(one, key=lambda t: -one[t][0])
    assert kendall_tau(order, truth) >= 0.8
    assert all(0 < se < 1 for _, se in one.values())  # it says how sure it is
    few = bradley_terry(matches[:20])
    assert max(se for _, se in few.values()) > max(se for _, se in one.values())  # fewer results, less sure
