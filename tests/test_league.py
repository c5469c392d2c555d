"""The league: one engine, submissions, formats, ratings, runners (local and Ray) and the CLI.

Matches here are short (demo_room, two robots a team, 60 simulated seconds, about half a
second each) so the whole file stays fast; the figures for full matches are bench/bench_league.py's.
"""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from robo_comp.errors import FieldError, UploadError
from robo_comp.league import reference, schedule, season
from robo_comp.league.engine import play_match, ranks_of
from robo_comp.league.ratings import kendall_tau
from robo_comp.league.runner import LocalRunner
from robo_comp.league.store import LeagueStore, version_of
from robo_comp.protocol.logfile import read_recording

SHORT = {"scenarios": ["demo_room"], "robots": 2, "seconds": 60}


def spec(tmp_path: Path, a: str = "frontier", b: str = "explorer", *, seed: int = 5, scenario: str = "demo_room",
         robots: int = 2, seconds: float = 60, log: str = "m.log") -> dict:
    return {"id": 1, "scenario": scenario, "seed": seed, "seconds": seconds, "robots": robots,
            "entrants": [{"team": a, "version": "x", "files": {"play.py": reference.source(a)}},
                         {"team": b, "version": "y", "files": {"play.py": reference.source(b)}}],
            "log": str(tmp_path / log)}


@pytest.fixture
def league(tmp_path):
    with LeagueStore(tmp_path / "lg", create=True) as store:
        store.configure(**SHORT)
        season.submit_reference(store, 4)
        yield store


# ------------------------------------------------------------------ one engine
def test_a_league_match_is_deterministic_to_the_byte(tmp_path):
    one = play_match(spec(tmp_path, "frontier", "random_walker", log="a.log"))
    two = play_match(spec(tmp_path, "frontier", "random_walker", log="b.log"))
    assert one["scores"] == two["scores"] and one["digest"] == two["digest"]
    assert (tmp_path / "a.log").read_bytes() == (tmp_path / "b.log").read_bytes()
    assert one["scores"]["frontier"] > 0  # the match did something worth comparing
    other = play_match(spec(tmp_path, "frontier", "random_walker", seed=6, log="c.log"))
    assert other["digest"] != one["digest"]  # the comparison can fail: the seed moves the random walker


def test_the_league_score_is_the_official_score(tmp_path):
    """The official core, recovering the match from the league's event log, keeps the same
    scores, finds and robots: the league match is a match like any other."""
    from robo_comp.core.replay import ReplayCore

    res = play_match(spec(tmp_path))
    records, started = read_recording(tmp_path / "m.log")
    assert started["teams"] == ["frontier", "explorer"]
    core = ReplayCore(tmp_path / "m.log", tmp_path / "replay-state")
    core.play(float("inf"), publish=False)
    official = {t: core.match.contest.board.score_of(t) for t in ("frontier", "explorer")}
    assert official == res["scores"] and res["scores"]["frontier"] > 0
    assert {r.tag for r in core.registry.robots.values()} == {101, 102, 103, 104}  # tags as a core gives them
    confirmed = [f for f in core.match.contest.judge.finds if f["state"] == "confirmed"]
    assert len(confirmed) == sum(len(v) for v in res["victims"].values()) > 0


def test_robo_comp_replay_serves_a_league_match(tmp_path):
    """A league log played by the real ``robo-comp replay`` process: consoles and walls see the
    robots and the scores as in a live match."""
    from robo_comp.client import Client
    from robo_comp.launch import _spawn, stop_all
    from robo_comp.testing import wait_for

    res = play_match(spec(tmp_path))
    state = tmp_path / "replay"
    state.mkdir()
    proc = _spawn(["replay", str(tmp_path / "m.log"), "--state", str(state), "--speed", "30"], state / "replay.log")
    try:
        wait_for(lambda: (state / "core.json").exists() or proc.poll() is not None, 20, "the replay to start")
        assert proc.poll() is None, (state / "replay.log").read_text()
        ref = Client(str(state), (state / "referee.token").read_text().strip())
        assert sorted(r["tag"] for r in ref.robots()) == [101, 102, 103, 104]

        def final():
            rows = {r["team"]: r["score"] for r in ref.request("score")["teams"]}
            return rows if rows == res["scores"] else None
        wait_for(final, 20, f"the replay to reach the final scores {res['scores']}")
        ref.close()
    finally:
        stop_all([proc])


def test_the_reference_explorer_loses_no_points_to_bumps(tmp_path):
    res = play_match(spec(tmp_path, "frontier", "random_walker", scenario="office", robots=4, seconds=300))
    assert res["bumps"]["frontier"] == 0
    assert res["scores"]["frontier"] >= 30  # it finds victims on the student's first map


def test_code_that_never_moves_cannot_hold_up_a_match(tmp_path):
    """A loop of calls that take no time would stop the simulated clock; past the robot's call
    budget (CALL_BURST at once) each is answered as the budget refills in simulated time, so
    the match still ends on time."""
    busy = reference.source("sitter").replace("def play(robot, width, height, index, count):\n",
                                              "def play(robot, width, height, index, count):\n"
                                              "    while True:\n        robot.sense()\n")
    s = spec(tmp_path, log="busy.log")
    s["entrants"][1] = {"team": "busy", "version": "b", "files": {"play.py": busy}}
    res = play_match(s)
    assert res["sim_seconds"] == 60 and res["scores"]["frontier"] > 0 and res["scores"]["busy"] == 0


def test_ranks_share_equal_scores():
    assert ranks_of({"a": 10, "b": 3, "c": 10}) == {"a": 1, "b": 3, "c": 1}


# ------------------------------------------------------------------ submissions
def test_a_submission_is_checked_like_an_upload_and_versioned(league, tmp_path):
    good = tmp_path / "good.py"
    good.write_text(reference.source("sitter"))
    files = season.read_submission(good)
    sub, new = season.submit(league, "rescuers", files, "ada")
    assert new and sub.version == version_of(files) and sub.who == "ada" and sub.at > 0
    again, new2 = season.submit(league, "rescuers", files, "bob")
    assert not new2 and again.id == sub.id  # the same files are the same version
    hostile = tmp_path / "hostile.py"
    hostile.write_text(reference.source("sitter").replace("HANDICAP = 0", "import os\nHANDICAP = 0"))
    with pytest.raises(UploadError) as e:
        season.submit(league, "rescuers", season.read_submission(hostile), "mallory")
    assert "hostile.py" in e.value.message and "os" in e.value.message
    no_play = tmp_path / "noplay.py"
    no_play.write_text(reference.source("sitter").replace('"play"', '"wait"').replace("def play(", "def wait("))
    with pytest.raises(FieldError, match="must advertise a task 'play'"):
        season.submit(league, "rescuers", season.read_submission(no_play), "ada")
    with pytest.raises(Exception, match="team name"):
        season.submit(league, "Bad Name!", files, "ada")
    assert [s.version for s in league.submissions("rescuers")] == [sub.version]  # nothing bad was stored


def test_a_new_team_folder_is_a_league_entry_and_plays(league, tmp_path):
    """What ``robo-comp new-team`` copies can be submitted as it is, and its play scores."""
    from robo_comp.teams.newteam import create_team

    files = season.read_submission(create_team("students", tmp_path))
    assert "play.py" in files and "explorer.py" in files
    sub, new = season.submit(league, "students", files, "ada")
    assert new
    ids = league.schedule("scrimmage", 1, [["students", "sitter"]])
    result = play_match(dict(league.spec(ids[0]), log=None))
    assert result["scores"]["students"] > 0


# ------------------------------------------------------------------ formats
def test_round_robin_meets_everyone_once_in_rounds_without_repeats():
    teams = [f"t{i}" for i in range(7)]
    rounds = schedule.round_robin(teams)
    pairs = [frozenset(p) for r in rounds for p in r]
    assert len(pairs) == len(set(pairs)) == 21
    for r in rounds:
        playing = [t for p in r for t in p]
        assert len(playing) == len(set(playing))


def test_swiss_avoids_rematches_and_double_elimination_needs_two_losses():
    standing = ["a", "b", "c", "d"]
    assert schedule.swiss_round(standing, []) == [["a", "b"], ["c", "d"]]
    assert schedule.swiss_round(standing, [frozenset("ab")]) == [["a", "c"], ["b", "d"]]
    met = [frozenset(p) for p in ("ab", "cd", "ef", "ac", "be", "df")]
    pairs = schedule.swiss_round(list("abcdef"), met)  # greedy would end in e-f again
    assert not {frozenset(p) for p in pairs} & set(met) and sorted(t for p in pairs for t in p) == list("abcdef")
    assert schedule.swiss_round(list("abcde"), [], byes=["e"]) == [["a", "b"], ["c", "e"]]  # d sits out
    assert schedule.swiss_round(list("ab"), [frozenset("ab")]) == [["a", "b"]]  # a rematch when nothing else
    everyone = [frozenset(p) for p in ("ab", "ac", "ad", "bc", "bd", "cd")]
    again = schedule.swiss_round(list("abcd"), everyone + [frozenset("ab"), frozenset("cd")])
    assert again == [["a", "c"], ["b", "d"]]  # all met: the pairs met least, not the same ones again
    losses: dict[str, int] = {}
    seeds = ["a", "b", "c", "d"]
    assert schedule.elimination_round(seeds, losses) == [["a", "d"], ["b", "c"]]
    rounds = 0
    while (pairs := schedule.elimination_round(seeds, losses)):  # the better seed always wins
        for x, y in pairs:
            loser = max(x, y, key=seeds.index)
            losses[loser] = losses.get(loser, 0) + 1
        rounds += 1
    assert schedule.champion(seeds, losses) == "a" and losses.get("a", 0) == 0
    assert sorted(losses.values()) == [2, 2, 2] and rounds <= 5


def test_a_season_plays_every_format_and_ratings_follow_results(league):
    runner = LocalRunner(1)
    fig = season.run_format(league, runner, "round-robin")
    assert fig["matches"] == 6 and not fig["failed"]
    view = season.league_view(league)
    assert [r["matches"] for r in view["standings"]] == [3, 3, 3, 3]
    best = view["standings"][0]
    assert best["wins"] >= 2 and best["rating"] == max(r["rating"] for r in view["standings"])
    before = league.ratings()
    test = season.run_format(league, runner, "scrimmage", rounds=1, ranked=False)
    assert test["matches"] == 2 and league.ratings() == before  # test matches do not move ratings
    seeded = season.standing(league)  # the seeds are the standing when the format starts (its results move it)
    fig = season.run_format(league, runner, "double-elimination")
    assert fig["champion"] in fig["seeds"] and fig["seeds"] == seeded
    swiss = season.run_format(league, runner, "swiss", rounds=2)
    assert swiss["matches"] == 4
    assert all(m.status == "done" for m in league.matches())
    assert all(league.log_path(m.id).is_file() for m in league.matches())  # every match keeps its log


def test_ratings_move_in_match_order_whatever_finishes_first(league, tmp_path):
    ids = league.schedule("scrimmage", 1, [["frontier", "sitter"], ["explorer", "random-walker"]])
    results = {mid: play_match(league.spec(mid)) for mid in ids}
    league.finished(ids[1], results[ids[1]])  # the second match ends first
    assert season.rate_played(league) == 0  # rated only once the first is in
    league.finished(ids[0], results[ids[0]])
    assert season.rate_played(league) == 2
    assert [mid for mid, _, _ in league.history()["frontier"]] == [ids[0]]


def test_a_stopped_run_leaves_nothing_behind_and_the_next_run_plays_it(league):
    """Ctrl-C mid-run: the unfinished matches are failed, not stuck running; the next run plays
    them, and every match is rated once, in order."""
    ids = league.schedule("scrimmage", 1, [["frontier", "sitter"], ["explorer", "random-walker"],
                                           ["frontier", "explorer"]])

    def interrupt(m) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        season.play(league, LocalRunner(1), on_match=interrupt)
    assert [m.status for m in league.matches()] == ["done", "failed", "failed"]
    assert "run stopped" in (league.match(ids[1]).error or "")
    league.started(ids[2])  # as a run killed with kill -9 leaves it
    fig = season.play(league, LocalRunner(1))
    assert fig["matches"] == 2 and all(m.status == "done" for m in league.matches())
    assert season.rate_played(league) == 0 and league.unrated() == []
    assert league.ratings()["frontier"][2] == 2  # rated once per match, not again


def test_a_match_that_cannot_be_played_is_named_and_can_be_cancelled(league, tmp_path):
    from robo_comp.league.report import standings_text

    gone = tmp_path / "gone.toml"
    gone.write_text((Path(__file__).parents[1] / "robo_comp/world/scenarios/demo_room.toml").read_text())
    league.configure(scenarios=[str(gone)])
    first = league.schedule("scrimmage", 1, [["frontier", "sitter"]])[0]
    league.configure(scenarios=["demo_room"])
    gone.unlink()
    fig = season.play(league, LocalRunner(1), league.schedule("scrimmage", 2, [["explorer", "sitter"]]))
    assert fig["failed"] == 0
    fig = season.play(league, LocalRunner(1), [first])
    assert fig["failed"] == 1 and league.match(first).status == "failed"
    held = season.rating_hold(league)
    assert held is not None and held["match"] == first and held["waiting"] == 1
    text = standings_text(season.league_view(league))
    assert f"Ratings wait for match {first}" in text and "league cancel" in text
    league.cancel(first, "its scenario file is gone")
    assert season.rate_played(league) == 1 and season.rating_hold(league) is None
    assert season.play(league, LocalRunner(1))["matches"] == 0  # a cancelled match is not played
    with pytest.raises(FieldError, match="has been played"):
        league.cancel(league.matches()[-1].id, "no")


def test_bad_team_lists_schedule_nothing(league):
    with pytest.raises(FieldError, match="typo have no submission"):
        season.run_format(league, LocalRunner(1), "round-robin", teams=["typo", "frontier", "sitter"])
    with pytest.raises(FieldError, match="at least 1"):
        season.run_format(league, LocalRunner(1), "swiss", rounds=0)
    with pytest.raises(FieldError, match="a team twice"):
        league.schedule("scrimmage", 1, [["frontier", "sitter"], ["explorer", "explorer"]])
    assert league.matches() == []  # one transaction: the good group before the bad one is not kept


def test_a_team_goes_back_to_an_earlier_version_by_submitting_it_again(league):
    old = {"play.py": reference.source("sitter")}
    new = {"play.py": reference.source("random_walker")}
    first, _ = season.submit(league, "rescuers", old, "ada")
    second, _ = season.submit(league, "rescuers", new, "ada")
    assert league.newest()["rescuers"].id == second.id
    again, fresh = season.submit(league, "rescuers", old, "ada")
    assert not fresh and again.id == first.id and league.newest()["rescuers"].id == first.id


def test_a_broken_league_file_is_a_clear_error(tmp_path):
    (tmp_path / "lg").mkdir()
    (tmp_path / "lg" / "league.db").write_bytes(b"this is not a database" * 100)
    with pytest.raises(FieldError, match="cannot be read as a league database"):
        LeagueStore(tmp_path / "lg")
    (tmp_path / "file").write_text("x")
    with pytest.raises(FieldError, match="is a file"):
        LeagueStore(tmp_path / "file", create=True)


def test_kendall_tau():
    assert kendall_tau(list("abcd"), list("abcd")) == 1.0
    assert kendall_tau(list("abcd"), list("dcba")) == -1.0
    assert kendall_tau(list("abcd"), list("bacd")) == pytest.approx(2 / 3)


def test_the_report_escapes_what_teams_name_and_says_when_nothing_was_played(league, tmp_path):
    from robo_comp.league.report import render_report, standings_text

    view = season.league_view(league)
    assert "No matches played yet." in render_report(view)
    evil = "<script>alert(1)</script>"
    view["standings"][0]["team"] = evil
    view["matches"] = [{"id": 1, "format": "scrimmage", "round": 1, "scenario": "demo_room", "seed": 1,
                        "ranked": True, "status": "done", "teams": [evil, "sitter"],
                        "scores": {evil: 3.0, "sitter": 0.0}, "log": "matches/1/events.log", "seconds": 1.0}]
    view["scores"] = {"demo_room": {evil: [3.0], "sitter": [0.0]}}
    page = render_report(view)
    assert evil not in page and "&lt;script&gt;alert(1)&lt;/script&gt;" in page
    assert evil in standings_text(view)  # plain text, not markup


# ------------------------------------------------------------------ runners
def test_two_local_workers_give_the_results_of_one(tmp_path):
    """And the workers stay up, warm, for the runner's next run (a Swiss season plays a run a
    round): the same processes play it, each match once; they end with the runner."""
    specs = [dict(spec(tmp_path, a, b, log=f"{a}-{b}.log"), id=i)
             for i, (a, b) in enumerate([("frontier", "sitter"), ("explorer", "random_walker")])]
    one: dict = {}
    LocalRunner(1).run(specs, lambda s, r: one.__setitem__(s["id"], r), pytest.fail)
    digests = {i: r["digest"] for i, r in one.items()}
    two: dict = {}
    played: list = []

    def took(s: dict, r: dict) -> None:
        played.append(s["id"])
        two[s["id"]] = r

    errors: list[str] = []
    with LocalRunner(2) as runner:
        runner.run(specs, took, pytest.fail)
        workers = [w.proc for w in runner._pool]
        assert len(workers) == 2 and all(w.is_alive() for w in workers)
        runner.run([dict(specs[0], scenario="nowhere", id=9)] * 2, pytest.fail, lambda s, m: errors.append(m))
        assert [w.proc for w in runner._pool] == workers  # the same warm workers played the second run
    assert not any(w.is_alive() for w in workers)
    assert sorted(played) == [0, 1]  # each match played once
    assert {i: r["digest"] for i, r in two.items()} == digests
    assert {i: r["scores"] for i, r in two.items()} == {i: r["scores"] for i, r in one.items()}
    assert len(errors) == 2 and all("Traceback" in m and "nowhere" in m.splitlines()[-1] for m in errors), errors
    assert all(r["cpu_seconds"] > 0 for r in two.values())


def test_longest_first_orders_by_the_teams_earlier_matches():
    from robo_comp.league.schedule import longest_first

    def row(mid: int, teams: list[str], cpu: float, scenario: str = "office") -> tuple:
        return teams, scenario, {"cpu_seconds": cpu, "sim_seconds": 100.0}

    def sp(mid: int, a: str, b: str, scenario: str = "office") -> dict:
        return {"id": mid, "scenario": scenario, "seconds": 100,
                "entrants": [{"team": a}, {"team": b}]}

    specs = [sp(1, "quick", "quicker"), sp(2, "slow", "quick"), sp(3, "new", "quick"), sp(4, "slow", "slow")]
    assert longest_first(specs, []) == specs  # no history: the order stays
    history = [row(10, ["slow", "quick"], 12.0), row(11, ["quick", "quicker"], 2.0), row(12, ["slow", "slow"], 20.0)]
    assert [s["id"] for s in longest_first(specs, history)] == [4, 2, 3, 1]
    # what a team's matches on another scenario cost does not count for this one
    assert longest_first(specs, [row(13, ["slow", "quick"], 50.0, "demo_room")]) == specs


@pytest.fixture(scope="module")
def ray_cluster():
    """A local Ray cluster of two nodes (two raylets, one CPU each), as ``ray start`` makes."""
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    cluster.add_node(num_cpus=1)
    cluster.wait_for_nodes()
    yield cluster
    import ray

    ray.shutdown()
    cluster.shutdown()


def test_a_season_on_a_two_node_ray_cluster_equals_the_local_one(tmp_path, ray_cluster):
    from robo_comp.league.runner import RayRunner

    results = {}
    for where in ("local", "ray"):
        with LeagueStore(tmp_path / where, create=True) as store:
            store.configure(**SHORT)
            season.submit_reference(store, 4)
            runner = RayRunner(ray_cluster.address) if where == "ray" else LocalRunner(1)
            if where == "ray":
                assert len([n for n in runner.ray.nodes() if n["Alive"]]) == 2 and runner.slots == 2
            season.run_format(store, runner, "round-robin")
            results[where] = ({m.id: (m.result["scores"], m.result["digest"]) for m in store.matches()},
                              store.ratings())
    assert results["ray"] == results["local"]


@pytest.mark.timeout(480)  # three plays of a 5-minute match (44 s on a quiet machine, past 120 s on a loaded one)
def test_a_ray_worker_killed_mid_match_has_its_match_played_again(tmp_path, ray_cluster):
    from robo_comp.league.runner import RayRunner

    s = spec(tmp_path, "frontier", "explorer", scenario="office", robots=4, seconds=300, log="local.log")
    local = play_match(s)
    runner = RayRunner(ray_cluster.address)
    killed: list[int] = []

    def kill_one() -> None:
        t_end = time.monotonic() + 60
        while time.monotonic() < t_end and not killed:
            out = subprocess.run(["ps", "-eo", "pid,args"], capture_output=True, text=True).stdout
            for line in out.splitlines():
                if "ray::play_match" in line:
                    pid = int(line.split()[0])
                    time.sleep(0.5)  # mid-match
                    os.kill(pid, 9)
                    killed.append(pid)
                    return
            time.sleep(0.02)

    killer = threading.Thread(target=kill_one)
    killer.start()
    got: dict = {}
    errors: list = []
    runner.run([dict(s, log=str(tmp_path / "ray.log"))], lambda sp, r: got.update(r), lambda sp, m: errors.append(m))
    killer.join()
    assert killed, "no Ray worker was seen running the match"
    assert not errors and got["scores"] == local["scores"] and got["digest"] == local["digest"]
    # the log came back from the worker and was written here, where the league keeps it
    assert got["log"] == str(tmp_path / "ray.log")
    assert hashlib.sha256((tmp_path / "ray.log").read_bytes()).hexdigest() == local["digest"]


def test_sandbox_limits_hold_inside_a_ray_worker(tmp_path, ray_cluster):
    """A hostile entry that computes forever is stopped by the sandbox's time limit inside the
    Ray worker (and not started again); the match ends and the other team's score stands."""
    from robo_comp.league.runner import RayRunner
    from robo_comp.protocol.logfile import read_log

    spinner = reference.source("sitter").replace("def play(robot, width, height, index, count):\n",
                                                 "def play(robot, width, height, index, count):\n"
                                                 "    while True:\n        pass\n")
    s = spec(tmp_path, log="hostile.log")
    s["entrants"][1] = {"team": "spinner", "version": "z", "files": {"play.py": spinner}}
    got: dict = {}
    RayRunner(ray_cluster.address).run([s], lambda sp, r: got.update(r), pytest.fail)
    assert got["scores"]["frontier"] > 0 and got["scores"]["spinner"] == 0
    done = [r.data for r in read_log(tmp_path / "hostile.log") if r.topic == "task.done" and r.team == "spinner"]
    assert len(done) == 2 and all(d["result"]["reason"] == "limit" and "time" in d["status"] for d in done), done


# ------------------------------------------------------------------ the command line
def robo(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "robo_comp.cli", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=300)


def test_a_season_from_the_command_line(tmp_path):
    r = robo("league", "init", "season", "--reference", "4", "--scenarios", "demo_room", "--robots", "2",
             "--seconds", "60", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "frontier" in r.stdout
    team = tmp_path / "mine.py"
    team.write_text(reference.source("sitter"))
    r = robo("league", "submit", "season", "mine", str(team), "--who", "ada", cwd=tmp_path)
    assert r.returncode == 0 and "mine version" in r.stdout, r.stderr
    r = robo("league", "run", "season", "--format", "round-robin", "--workers", "2", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "played 10 matches" in r.stdout and "[10/10]" in r.stderr
    r = robo("league", "table", "season", "--json", cwd=tmp_path)
    view = json.loads(r.stdout)
    assert len(view["standings"]) == 5 and len(view["matches"]) == 10
    assert view["standings"][0]["rating"] >= view["standings"][-1]["rating"]
    r = robo("league", "report", "season", "out/report.html", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    page = (tmp_path / "out" / "report.html").read_text()
    # a match's log is given as the command that replays it, not as a link to a binary file
    assert page.count("<svg") == 2 and "<code>robo-comp web --replay ../season/matches/1/events.log</code>" in page
    assert "events.log'>" not in page and "<a href" not in page
    # sixteen teams, sixteen colours (matplotlib's cycle has ten)
    from robo_comp.scoring.results import team_colours

    assert len(set(team_colours([f"t{i}" for i in range(16)]).values())) == 16
    assert (tmp_path / "out" / "../season/matches/1/events.log").is_file()
    r = robo("league", "table", "season", cwd=tmp_path)
    assert r.returncode == 0 and view["standings"][0]["team"] in r.stdout.splitlines()[4]
    r = robo("league", "submit", "season", "mine", str(tmp_path / "nothing.py"), cwd=tmp_path)
    assert r.returncode == 2 and "no such file" in r.stderr and "Traceback" not in r.stderr
    r = robo("league", "run", "nowhere", cwd=tmp_path)
    assert r.returncode == 2 and "not a league" in r.stderr
    r = robo("league", "run", "season", "--teams", "mine", cwd=tmp_path)
    assert r.returncode == 2 and "without --format" in r.stderr
    r = robo("league", "init", "three", "--teams-per-match", "3", cwd=tmp_path)
    assert r.returncode == 2 and "start zones for 2 teams" in r.stderr and "Traceback" not in r.stderr
    r = robo("league", "cancel", "season", "999", cwd=tmp_path)
    assert r.returncode == 2 and "no match 999" in r.stderr
