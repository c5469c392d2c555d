"""The league survives its workers, its operator and its disk (issue 32, the league; issue 26,
Ctrl-C): real `robo-comp league run` processes, real signals, real bytes changed in league.db.
"""
from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from robo_comp.league.store import LeagueStore

LEAGUE = ["--reference", "4", "--scenarios", "demo_room", "--robots", "2", "--seconds", "40"]


def robo(*args: str, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "robo_comp.cli", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout)


def start_run(cwd: Path, *args: str) -> subprocess.Popen:
    """`league run` in its own session and process group, as a terminal would start it."""
    return subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "league", "run", "lg", *args], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def children(pid: int) -> list[int]:
    """Every descendant of ``pid`` (sandbox children too, which start their own sessions)."""
    kids: dict[int, list[int]] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            kids.setdefault(ppid, []).append(int(d.name))
    out, todo = [], [pid]
    while todo:
        for k in kids.get(todo.pop(), []):
            out.append(k)
            todo.append(k)
    return out


def alive(pid: int) -> bool:
    try:
        state = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


def wait_for(cond, what: str, timeout: float = 120.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got = cond()
        if got:
            return got
        time.sleep(0.05)
    pytest.fail(f"timed out waiting for {what}")


def statuses(root: Path) -> dict[str, int]:
    with LeagueStore(root) as store:
        out: dict[str, int] = {}
        for m in store.matches():
            out[m.status] = out.get(m.status, 0) + 1
        return out


def match_workers(run: subprocess.Popen) -> list[int]:
    """The run's worker processes (the spawn interpreters), once they play."""
    return [p for p in children(run.pid) if "spawn_main" in _cmdline(p)]


def _cmdline(pid: int) -> str:
    try:
        return (Path("/proc") / str(pid) / "cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


@pytest.fixture
def league(tmp_path):
    r = robo("league", "init", "lg", *LEAGUE, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    return tmp_path


def schedule_round_robin(root: Path) -> list[int]:
    from robo_comp.league import schedule

    with LeagueStore(root / "lg") as store:
        groups = schedule.round_robin(sorted(store.newest()), 2)
        return [mid for i, g in enumerate(groups) for mid in store.schedule("round-robin", i + 1, g)]


# ------------------------------------------------------------------ Ctrl-C
def test_ctrl_c_stops_a_run_at_once_and_the_next_run_plays_the_rest(league):
    ids = schedule_round_robin(league)
    run = start_run(league, "--workers", "2")
    wait_for(lambda: match_workers(run) and statuses(league / "lg").get("running"), "matches to start")
    tree = children(run.pid)
    os.killpg(run.pid, signal.SIGINT)  # what Ctrl-C in a terminal does: the whole foreground group
    t0 = time.monotonic()
    out, err = run.communicate(timeout=60)
    stopped_in = time.monotonic() - t0
    assert run.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    line = [ln for ln in err.splitlines() if ln.startswith("stopped:")]
    assert line and "stopped while playing" in line[0] and "'robo-comp league run lg' plays them" in line[0], err
    assert stopped_in < 10, stopped_in  # at once: a match takes about as long
    wait_for(lambda: not any(alive(p) for p in tree), "the workers and sandboxes to end", timeout=20)
    st = statuses(league / "lg")
    assert "running" not in st and st.get("failed", 0) + st.get("scheduled", 0) >= 1, st
    r = robo("league", "run", "lg", "--workers", "2", cwd=league)
    assert r.returncode == 0, r.stderr
    assert statuses(league / "lg") == {"done": len(ids)}


PRESSED_WHILE_STARTING = r"""
import multiprocessing, os, signal, sys, time
from robo_comp.league.runner import _Worker

ctx = multiprocessing.get_context("spawn")
start = ctx.Process.start
started = []

def pressed_meanwhile(self):
    os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C, delivered to the run during the start ...
    start(self)
    started.append(self.pid)
    os.kill(self.pid, signal.SIGINT)  # ... and to the worker while its interpreter starts up

ctx.Process.start = pressed_meanwhile
try:
    _Worker(ctx)
    time.sleep(1.0)
    print("the run played on")
except KeyboardInterrupt:
    time.sleep(1.0)
    alive = [p.pid for p in multiprocessing.active_children() if p.exitcode is None]
    print("stopped; worker alive" if alive == started else f"stopped; worker gone {alive} {started}")
"""


def test_ctrl_c_while_a_worker_starts_is_not_lost() -> None:
    """A Ctrl-C that comes while the run starts a worker process (pressed as the second worker
    starts, say) stops the run once the worker is up, and the worker ignores its own (no traceback
    from a half-started interpreter). Before, the run ignored Ctrl-C during each start and played
    on. In a process of its own, as ``league run`` is (one thread when it starts its workers)."""
    out = subprocess.run([sys.executable, "-c", PRESSED_WHILE_STARTING], capture_output=True, text=True, timeout=60)
    assert out.stdout.strip() == "stopped; worker alive", (out.stdout, out.stderr)
    assert "Traceback" not in out.stderr, out.stderr


# ------------------------------------------------------------------ dead workers, kills, the lock
def test_a_killed_worker_costs_only_its_match_which_is_played_again(league, tmp_path):
    ids = schedule_round_robin(league)
    run = start_run(league, "--workers", "2")
    workers = wait_for(lambda: statuses(league / "lg").get("running") and match_workers(run), "a worker to play")
    os.kill(workers[0], signal.SIGKILL)
    out, err = run.communicate(timeout=300)
    assert run.returncode == 0, err
    assert "BrokenProcessPool" not in err and "Traceback" not in err
    assert statuses(league / "lg") == {"done": len(ids)}
    # the match played again is the same match: a one-worker run of a copy gives the same logs
    with LeagueStore(league / "lg") as store:
        digests = {m.id: m.result["digest"] for m in store.matches()}
    from robo_comp.league.engine import play_match

    with LeagueStore(league / "lg") as store:
        for mid in ids:
            again = play_match(dict(store.spec(mid), log=str(tmp_path / f"again-{mid}.log")))
            assert again["digest"] == digests[mid], mid


def test_kill_9_of_the_run_leaves_no_process_and_no_lock(league):
    ids = schedule_round_robin(league)
    run = start_run(league, "--workers", "2")
    wait_for(lambda: len(match_workers(run)) == 2 and statuses(league / "lg").get("running"), "two workers")
    wait_for(lambda: any("sandbox.child" in _cmdline(p) for p in children(run.pid)), "sandboxes")
    tree = children(run.pid)
    os.kill(run.pid, signal.SIGKILL)
    run.communicate(timeout=30)
    wait_for(lambda: not any(alive(p) for p in tree), "every worker, sandbox and tracker to end", timeout=30)
    r = robo("league", "run", "lg", "--workers", "2", cwd=league)  # the lock died with the run
    assert r.returncode == 0, r.stderr
    assert statuses(league / "lg") == {"done": len(ids)}


def test_one_run_per_league_at_a_time(league):
    schedule_round_robin(league)
    run = start_run(league, "--workers", "1")
    wait_for(lambda: statuses(league / "lg").get("running"), "the first run to play")
    r = robo("league", "run", "lg", cwd=league)
    assert r.returncode == 2 and "another 'league run' is playing" in r.stderr and f"pid {run.pid}" in r.stderr
    assert "Traceback" not in r.stderr
    os.killpg(run.pid, signal.SIGINT)
    run.communicate(timeout=60)


# ------------------------------------------------------------------ a damaged league.db
def test_a_damaged_result_is_a_sentence_and_repair_plays_the_match_again(league):
    r = robo("league", "run", "lg", "--format", "round-robin", "--teams", "frontier,sitter", cwd=league)
    assert r.returncode == 0, r.stderr
    with LeagueStore(league / "lg") as store:
        before = store.match(1).result
        store.db.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    db = league / "lg" / "league.db"
    data = bytearray(db.read_bytes())
    at = data.find(b'"digest": "')
    assert at > 0
    data[at + len(b'"digest"')] = ord("#")  # one changed byte inside the stored JSON (its colon)
    db.write_bytes(bytes(data))
    for cmd in (["table", "lg"], ["run", "lg"]):
        r = robo("league", *cmd, cwd=league)
        assert r.returncode == 2, r.stdout
        assert "league.db is damaged: match 1's result cannot be read" in r.stderr, r.stderr
        assert "robo-comp league repair" in r.stderr and "Traceback" not in r.stderr
    r = robo("league", "repair", "lg", cwd=league)
    assert r.returncode == 0 and "match 1: its result was damaged" in r.stdout, r.stdout + r.stderr
    assert list((league / "lg").glob("league.db.damaged-*"))
    r = robo("league", "run", "lg", cwd=league)
    assert r.returncode == 0, r.stderr
    with LeagueStore(league / "lg") as store:
        assert store.match(1).result["digest"] == before["digest"]


def test_a_damaged_page_is_a_sentence_and_repair_keeps_what_can_be_read(league):
    r = robo("league", "run", "lg", "--format", "round-robin", "--teams", "frontier,sitter", cwd=league)
    assert r.returncode == 0, r.stderr
    with LeagueStore(league / "lg") as store:
        store.db.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        page = store.db.execute("PRAGMA page_size").fetchone()[0]
        teams = sorted(store.newest())
    db = league / "lg" / "league.db"
    data = bytearray(db.read_bytes())
    # damage every page that holds match rows (the table's b-tree), not the schema page
    conn = sqlite3.connect(db)
    root = conn.execute("SELECT rootpage FROM sqlite_master WHERE name = 'matches'").fetchone()[0]
    conn.close()
    start = (root - 1) * page
    data[start:start + 100] = b"\xff" * 100
    db.write_bytes(bytes(data))
    r = robo("league", "table", "lg", cwd=league)
    assert r.returncode == 2 and "league.db is damaged" in r.stderr and "Traceback" not in r.stderr, r.stderr
    r = robo("league", "repair", "lg", cwd=league)
    assert r.returncode == 0, r.stderr
    r = robo("league", "table", "lg", "--json", cwd=league)
    assert r.returncode == 0, r.stderr
    assert sorted(row["team"] for row in json.loads(r.stdout)["standings"]) == teams  # submissions kept


def test_a_busy_league_db_is_not_called_damaged(league):
    """Another program holding league.db's write lock (or a full disk, a file that cannot be
    written) is not damage: the sentence says so and does not send the organiser to
    'league repair'; bytes that are not a database still do."""
    from robo_comp.league.store import LeagueDamaged, db_error

    root = league / "lg"
    holder = sqlite3.connect(root / "league.db", isolation_level=None)
    holder.execute("BEGIN IMMEDIATE")
    other = sqlite3.connect(root / "league.db", isolation_level=None, timeout=0)
    try:
        with pytest.raises(sqlite3.OperationalError) as busy:
            other.execute("BEGIN IMMEDIATE")
    finally:
        other.close()
        holder.execute("ROLLBACK")
        holder.close()
    err = db_error(root, busy.value, "damaged")
    assert not isinstance(err, LeagueDamaged)
    assert "not damaged" in str(err) and "repair" not in str(err) and "locked" in str(err)
    junk = root / "junk.db"
    junk.write_bytes(b"not a database " * 400)
    with pytest.raises(sqlite3.DatabaseError) as notadb:
        sqlite3.connect(junk).execute("SELECT * FROM sqlite_master")
    damaged = db_error(root, notadb.value, f"SQLite says {notadb.value}")
    assert isinstance(damaged, LeagueDamaged) and "league repair" in str(damaged)
