"""Faults of the machine, with real processes: a full disk under the core's state folder, and the
core or a robot host stopped (SIGSTOP) past the heartbeat. ``docs/reliability.md`` states the
promise each test checks."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from typing import Any
from pathlib import Path

import pytest

from conftest import CoreHandle, next_event_where, wait_for, wait_robots
from robo_comp.errors import FieldError, StorageError, TimeoutError_, UnavailableError
from robo_comp.launch import start_core


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 4 MiB tmpfs: the core's state folder on a disk that can be filled."""
    where = tmp_path / "disk"
    where.mkdir()
    try:
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4m", "tmpfs", str(where)], check=True,
                       capture_output=True, timeout=10)
    except (OSError, subprocess.SubprocessError) as e:
        pytest.skip(f"cannot mount a small tmpfs here (needs root): {e}")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], capture_output=True, timeout=10)


def fill(disk: Path) -> Path:
    """Fill ``disk`` up to the last byte with one file; return it."""
    filler = disk / "filler"
    with open(filler, "wb", buffering=0) as f:
        for size in (65536, 512, 1):
            try:
                while f.write(b"\0" * size):
                    pass
            except OSError:
                pass
    return filler


def test_a_full_disk_refuses_changes_keeps_stops_and_resumes_by_itself(small_disk: Path) -> None:
    state = small_disk / "state"
    proc = start_core(state, "--heartbeat", "0.2", "--teams", "red,blue")
    match = CoreHandle(state, None, proc)
    try:
        host = match.robots("red", 2)
        red = match.client("red")
        ref = match.referee()
        ref.watch(True)
        rows = wait_robots(red, 2)
        a, b = rows[0]["tag"], rows[1]["tag"]
        acked = [red.give(a, "goTo", [8, 8])["task_id"]]
        # b has a queue before the disk fills, so the stop below always has something to cancel
        # (the disk may refuse the very first task given after it fills)
        acked += [red.give(b, "goTo", [9, 1], queue=True)["task_id"] for _ in range(2)]
        filler = fill(small_disk)
        quick = match.client("red", timeout=1.0)
        refused = None
        for _ in range(500):  # queued tasks fill the last page of the log's file, then the disk says no
            try:
                acked.append(quick.give(b, "goTo", [2, 2], queue=True)["task_id"])
            except TimeoutError_:
                quick = match.client("red", timeout=1.0)  # its answer waits for the log: not acknowledged
            except StorageError as e:
                refused = e
                break
        assert refused is not None and "cannot write its event log" in refused.message, refused
        fault = next_event_where(ref, lambda e: e["topic"] == "core.storage", 5.0)
        assert fault["data"]["ok"] is False and "free space" in fault["data"]["message"]
        assert ref.request("stats")["storage"]
        with pytest.raises(StorageError, match="cannot write its event log"):
            red.give(b, "goTo", [2, 2])
        with pytest.raises(StorageError):
            ref.match("start")
        assert {r["tag"] for r in red.robots()} == {a, b}  # reads go on
        stopped = red.stop(b)  # a stop is carried out at once: b's queue is cancelled
        assert stopped["tag"] == b and stopped["cancelled"]
        assert red.monitor(a)["status"] == "connected"  # heartbeats went on: nobody was lost
        filler.unlink()
        back = next_event_where(ref, lambda e: e["topic"] == "core.storage" and e["data"]["ok"], 5.0)
        assert back["data"]["seconds"] > 0
        acked.append(red.give(b, "goTo", [2, 2])["task_id"])
        assert ref.request("stats")["storage"] is None
        # everything acknowledged is in the log (a core killed now recovers it), the stop too. The
        # robot host goes first, so what the core recovers is the log's alone: a host that came
        # back would cancel a task it no longer runs (it halts when it loses the core).
        host.kill()
        proc.kill()
        host.wait()
        proc.wait()
        given = {e["data"]["task_id"] for e in match.logged_events("task.given")}
        assert set(acked) <= given, sorted(set(acked) - given)
        assert any(e["data"]["tag"] == b for e in match.logged_events("robot.stopped"))
        match.proc = start_core(state, "--heartbeat", "0.2", "--teams", "red,blue")
        recovered = match.client("referee").tasks(b)
        # the stop held: nothing it cancelled came back; the task given after it is b's task
        assert recovered["queued"] == [] and recovered["pending"] is None, recovered
        assert recovered["current"] is not None and recovered["current"]["task_id"] == acked[-1], recovered
    finally:
        match.close()


def test_a_core_stopped_past_the_heartbeat_loses_nothing(core: CoreHandle) -> None:
    core.robots("red", 2)
    red = core.client("red")
    rows = wait_robots(red, 2)
    tags = sorted(r["tag"] for r in rows)
    given = red.give(tags[0], "goTo", [9, 9], queue=True)["task_id"]
    os.kill(core.proc.pid, signal.SIGSTOP)
    try:
        time.sleep(2.0)  # ten heartbeats: the hosts halt their robots and try to reconnect
    finally:
        os.kill(core.proc.pid, signal.SIGCONT)
    # Right after SIGCONT the core may still list the robots as connected: its sweep has not yet
    # run. It then marks them lost until their hosts' new connections come in; a give meanwhile
    # is refused (E_UNAVAILABLE) as it should be. What must hold is that they come back.
    def back() -> int | None:
        try:
            return int(red.give(tags[1], "goTo", [3, 3])["task_id"])
        except UnavailableError:
            return None
    later = wait_for(back, 20.0, "the robot to take a task again")
    assert later > given
    rows = wait_robots(red, 2, timeout=20.0)
    assert sorted(r["tag"] for r in rows) == tags  # the same tags
    tasks = red.tasks(tags[0])
    assert given in {t["task_id"] for t in [*tasks["done"], *filter(None, [tasks["current"]]), *tasks["queued"]]}


def test_a_host_stopped_past_the_heartbeat_is_lost_then_returns_with_its_tags(core: CoreHandle) -> None:
    host = core.robots("red", 2)
    red = core.client("red")
    tags = sorted(r["tag"] for r in wait_robots(red, 2))
    os.kill(host.pid, signal.SIGSTOP)
    try:
        wait_robots(red, 2, status="lost", timeout=10.0)
    finally:
        os.kill(host.pid, signal.SIGCONT)
    assert sorted(r["tag"] for r in wait_robots(red, 2, timeout=20.0)) == tags


def test_a_restart_keeps_the_match_it_recovers(tmp_path: Path) -> None:
    """The teams, scenario and options come from the state folder; a contradicting option is
    refused with what to do, and applied only with --override."""
    state = tmp_path / "state"
    first = start_core(state, "--heartbeat", "0.2", "--teams", "red", "--pose-hz", "4")
    port = json.loads((state / "core.json").read_text())["router"].rsplit(":", 1)[1]
    first.kill()
    first.wait()
    again = start_core(state)  # no options at all: the recovered match's, its port included
    try:
        info = json.loads((state / "core.json").read_text())
        assert info["teams"] == ["red"] and info["router"].endswith(":" + port) and info["heartbeat"] == 0.2
        assert not (state / "teams" / "blue.token").exists()
    finally:
        again.terminate()
        again.wait(10)
    out = subprocess.run([sys.executable, "-m", "robo_comp.cli", "core", "--state", str(state),
                          "--teams", "red,blue", "--pose-hz", "10"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 2
    assert "--teams red,blue (the match has red)" in out.stderr and "--pose-hz 10.0 (the match has 4.0)" in out.stderr
    assert "--override" in out.stderr and "empty --state folder" in out.stderr
    overridden = start_core(state, "--teams", "red,blue", "--override")
    try:
        assert json.loads((state / "core.json").read_text())["teams"] == ["red", "blue"]
        assert json.loads((state / "match.json").read_text())["teams"] == ["red", "blue"]
    finally:
        overridden.terminate()
        overridden.wait(10)


def test_a_burst_of_tasks_while_the_core_is_killed_in_a_loop(tmp_path: Path) -> None:
    """Thousands of pipelined gives, the core killed mid-stream five times: every acknowledged
    task is in the log, none is logged twice, none finishes twice."""
    from robo_comp.client import Client
    from robo_comp.protocol.logfile import read_log
    from robo_comp.launch import start_robots, stop_all

    state = tmp_path / "state"
    core = start_core(state, "--heartbeat", "0.3", "--teams", "red")
    host = start_robots(state, "red", 3)
    acked: list[int] = []
    try:
        for cycle in range(5):
            red = Client(str(state), (state / "teams/red.token").read_text().strip(), timeout=10)
            tags = [r["tag"] for r in wait_robots(red, 3, timeout=20)]
            rids = [red.ask("give", tag=tags[i % 3], task="goTo", args=[1 + i % 9, 1 + i % 7], queue=True)
                    for i in range(500)]
            time.sleep(0.02 * (cycle + 1))  # some answered, many in flight
            core.kill()
            core.wait()
            for rid in rids:  # the answers that arrived before the kill
                try:
                    reply = red.answer(rid)
                except Exception:  # refused (e.g. a robot lost mid-burst): not acknowledged
                    continue
                if reply is not None:
                    acked.append(reply["task_id"])
            red.close()
            core = start_core(state)  # the recorded match: its teams, port and options
        assert len(acked) > 100
        given = [r.data["task_id"] for r in read_log(state / "events.log", strict=False) if r.topic == "task.given"]
        done = [r.data["task_id"] for r in read_log(state / "events.log", strict=False) if r.topic == "task.done"]
        assert set(acked) <= set(given), sorted(set(acked) - set(given))[:10]
        assert len(given) == len(set(given)), "a task was logged as given twice"
        assert len(done) == len(set(done)), "a task finished twice"
    finally:
        stop_all([host, core])


def test_latency_and_a_dead_link_between_a_host_and_the_core(core: CoreHandle) -> None:
    """Through a link that delays every byte by 50-150 ms the match goes on; a link that carries
    nothing for 2.5 s (ten heartbeats) makes the robots stop moving and be marked lost, and they
    come back with the same tags when it carries bytes again. (No netem here: see faultproxy.)"""
    from faultproxy import DelayProxy

    port = int(json.loads((core.state / "core.json").read_text())["router"].rsplit(":", 1)[1])
    proxy = DelayProxy(port, delay=0.05, jitter=0.1, seed=3).start()
    host = subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "robots", "--core", proxy.url, "--token-file",
                             str(core.host_token_file("red")), "--count", "2", "--speed", "4"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
    core.procs.append(host)
    try:
        red = core.client("red")
        rows = wait_robots(red, 2, timeout=20)
        tags = sorted(r["tag"] for r in rows)
        red.watch(True)
        given = red.give(tags[0], "goTo", [3, 3])["task_id"]
        done = next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == given, 20.0)
        assert done["data"]["ok"], done
        assert red.stop(tags[0])["ms"] >= 50  # the stop crossed the slow link both ways
        far = red.give(tags[1], "goTo", [18, 12])["task_id"]  # a long way at 4 cells/s
        time.sleep(0.5)
        before = red.monitor(tags[1])
        proxy.stall(2.5)
        lost = wait_robots(red, 2, status="lost", timeout=5)
        assert sorted(r["tag"] for r in lost) == tags
        back = {r["tag"]: r for r in wait_robots(red, 2, timeout=20)}
        assert sorted(back) == tags
        moved = abs(back[tags[1]]["x"] - before["x"]) + abs(back[tags[1]]["y"] - before["y"])
        assert moved < 6, f"the robot drove on without the core: {moved:.1f} cells in 2.5 s"  # 10 if it had
        assert far >= 1
    finally:
        proxy.close()


def _libfaketime() -> str | None:
    """The multi-threaded libfaketime from Debian's package, where it is installed."""
    import glob

    found = glob.glob("/usr/lib/*/faketime/libfaketimeMT.so.1")
    return found[0] if found else None


def test_a_host_whose_clock_runs_fast_and_jumps(core: CoreHandle, tmp_path: Path) -> None:
    """A robot host under libfaketime: its clock runs twice as fast, then jumps 2 h forward, then
    1 h back. Robots keep their tags, no task finishes twice, no duration is negative."""
    lib = _libfaketime()
    if lib is None:
        pytest.skip("libfaketime is not installed (Debian package faketime; .ci/run installs it)")
    clock = tmp_path / "faketime.rc"
    clock.write_text("+0 x2\n")
    env = dict(os.environ, LD_PRELOAD=lib, FAKETIME_TIMESTAMP_FILE=str(clock), FAKETIME_NO_CACHE="1")
    host = subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "robots", "--core", str(core.state),
                             "--token-file", str(core.host_token_file("red")), "--count", "2"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL, env=env)
    core.procs.append(host)
    red = core.client("red")
    tags = sorted(r["tag"] for r in wait_robots(red, 2, timeout=30))
    red.watch(True)
    ids = []
    for step, when in enumerate(("+0 x2", "+7200 x2", "+3600 x1")):
        clock.write_text(when + "\n")
        time.sleep(1.0)  # a forward jump looks like a silent core to the host: it may re-register
        assert sorted(r["tag"] for r in wait_robots(red, 2, timeout=20)) == tags
        ids.append(red.give(tags[step % 2], "goTo", [2 + step, 3])["task_id"])
        next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == ids[-1], 30.0)
    done = [e["data"] for e in core.logged_events("task.done")]
    assert len({d["task_id"] for d in done}) == len(done), "a task finished twice"
    for tag in tags:
        for t in red.tasks(tag)["done"]:
            if t["started_at"] is not None:  # (a task cancelled before it started has none)
                assert t["finished_at"] >= t["started_at"] >= t["given_at"] - 1e-6, t


def test_a_console_stopped_past_the_heartbeat_holds_up_nothing(core: CoreHandle, tmp_path: Path) -> None:
    """A console (``ctl events``) SIGSTOPped for ten heartbeats: the match goes on without it, and
    when it runs again it gets the events it missed and the new ones."""
    core.robots("red", 1)
    red = core.client("red")
    tag = wait_robots(red, 1)[0]["tag"]
    out = tmp_path / "events.jsonl"
    with open(out, "w") as f:
        console = subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "ctl", "--core", str(core.state),
                                    "--token-file", str(core.token_file("red")), "--json", "events",
                                    "--timeout", "6"], stdout=f, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
    core.procs.append(console)
    t_end = time.monotonic() + 10
    while not out.read_text():  # it watches: its first event has come
        assert time.monotonic() < t_end, "the console printed nothing"
        red.give(tag, "goTo", [2, 2])
        time.sleep(0.3)
    os.kill(console.pid, signal.SIGSTOP)
    try:
        during = red.give(tag, "goTo", [3, 3])["task_id"]  # the match does not wait for the console
        time.sleep(2.0)
        assert red.monitor(tag)["status"] == "connected"
    finally:
        os.kill(console.pid, signal.SIGCONT)
    after = red.give(tag, "goTo", [4, 4])["task_id"]
    console.wait(30)
    given = {json.loads(line)["data"].get("task_id") for line in out.read_text().splitlines()
             if json.loads(line)["topic"] == "task.given"}
    assert {during, after} <= given, given


# ---------------------------------------------------------------------------------------------
# Records that prove themselves (issue 32): a damaged byte costs the record it is in, no more.


def _flip(path: Path, offset: int, bits: int = 0x09) -> None:
    """Change one byte of ``path`` in place."""
    with open(path, "r+b") as f:
        f.seek(offset)
        b = f.read(1)[0]
        f.seek(offset)
        f.write(bytes([b ^ bits]))


def _kill9_between_writes(proc: subprocess.Popen[bytes]) -> None:
    """``kill -9`` the core, but not in the middle of a write to its log: stopped first (a stop takes
    effect between system calls), so that the test's own damage is the log's only one. (A record
    torn by a kill is the case of ``tests/test_recovery.py``.)"""
    os.kill(proc.pid, signal.SIGSTOP)
    t_end = time.monotonic() + 10
    while Path(f"/proc/{proc.pid}/stat").read_text().rsplit(")", 1)[1].split()[0] not in ("T", "t"):
        assert time.monotonic() < t_end, "the core did not stop"
        time.sleep(0.01)
    proc.kill()
    proc.wait()


def test_one_damaged_byte_in_the_middle_of_the_log_costs_that_record_only(tmp_path: Path) -> None:
    """The core is killed, a penalty's score line in the middle of the log has its points changed
    (-1 would read as -1.25), the core restarts: that one record is reported lost (by seq and
    topic), every record after it recovers, the file is not cut, and no sequence number is used
    twice; then the last record is damaged too, and the next restart reuses none of its numbers."""
    from robo_comp.protocol.logfile import read_log

    state = tmp_path / "state"
    log = state / "events.log"
    proc = start_core(state, "--heartbeat", "0.2", "--teams", "red,blue")
    match = CoreHandle(state, None, proc)
    try:
        ref = match.referee()
        for i in range(30):
            ref.request("penalty", team=("red", "blue")[i % 2], points=-1, reason=f"foul {i:02d}")
        _kill9_between_writes(proc)
        raw = log.read_bytes()
        size = len(raw)
        lines = [r for r in read_log(log) if r.topic == "score.change"]
        assert len(lines) == 30
        victim = next(r for r in lines if r.data["reason"] == "foul 15")
        at = raw.index(b"foul 15", raw.index(b"foul 15") + 1)  # the second: the score line's
        points = raw.rindex(b"\xa6points", 0, at) + 7
        assert raw[points:points + 3] == b"\xcb\xbf\xf0"  # msgpack's float64 -1.0
        _flip(log, points + 2, 0x04)  # -1.25
        before = [(r.seq, r.topic) for r in read_log(log, strict=False)]
        match.proc = proc = start_core(state)
        ref = match.referee()
        rec = ref.request("stats")["recovered"]
        assert rec["lost"] == [victim.seq], rec
        assert rec["damages"][0]["lost"] == [{"seq": victim.seq, "topic": "score.change"}], rec
        assert "1 event lost" in rec["damage"] and f"{victim.seq} (probably score.change)" in rec["damage"]
        shown_ctl = subprocess.run([sys.executable, "-m", "robo_comp.cli", "ctl", "--core", str(state), "--token-file",
                                    str(state / "referee.token"), "recovery"], capture_output=True, text=True, timeout=60)
        assert f"lost event {victim.seq} (probably score.change)" in shown_ctl.stdout, shown_ctl
        assert log.stat().st_size >= size  # nothing was cut
        shown = ref.score()["lines"]
        assert sorted(ln["reason"] for ln in shown) == sorted(f"foul {i:02d}" for i in range(30) if i != 15)
        assert {ln["points"] for ln in shown} == {-1}, "a changed value was read back"
        ref.request("penalty", team="red", points=-1, reason="after the restart")
        seqs = [r.seq for r in read_log(log, strict=False)]
        assert len(seqs) == len(set(seqs)), "a sequence number was used twice"
        assert [(s, t) for s, t in before] == [(r.seq, r.topic) for r in read_log(log, strict=False)][:len(before)]
        # now the last record: an unfinished write or a damaged byte at the very end
        _kill9_between_writes(proc)
        last = list(read_log(log, strict=False))[-1]
        _flip(log, log.stat().st_size - 3)
        match.proc = proc = start_core(state)
        ref = match.referee()
        rec = ref.request("stats")["recovered"]
        assert set(rec["lost"]) == {victim.seq, last.seq}, rec
        assert rec["damages"][-1]["tail"] and rec["damaged_copy"], rec
        ref.request("penalty", team="blue", points=-1, reason="after the second restart")
        after = list(read_log(log, strict=False))
        assert len({r.seq for r in after}) == len(after), "a sequence number was used twice"
        assert all(r.seq > last.seq for r in after if r.t > last.t and r.topic == "penalty"), \
            "the damaged last record's number was given to a new event"
        assert "after the second restart" in {ln["reason"] for ln in ref.score()["lines"]}
    finally:
        match.close()


def test_every_single_damaged_byte_costs_at_most_its_record_and_is_reported(tmp_path: Path) -> None:
    """Each byte of a log, changed in turn: at most the one record it belongs to is lost, exactly
    its sequence number is reported, and no record reads back changed (the checksum)."""
    from robo_comp.core.eventlog import EventLog
    from robo_comp.protocol.logfile import LogReader

    path = tmp_path / "events.log"
    ev = EventLog(path)
    for i in range(12):
        ev.append(("penalty", "score.change", "robot.positions")[i % 3], "red",
                  {"points": -1, "i": i, "x": [1.5, 2.5]}, t=1000.0 + i)
    ev.close()
    raw = path.read_bytes()
    good = {r.seq: r for r in LogReader(path)}
    assert len(good) == 12
    bad = tmp_path / "damaged.log"
    for off in range(len(raw)):
        damaged = bytearray(raw)
        damaged[off] ^= 0x10
        bad.write_bytes(bytes(damaged))
        reader = LogReader(bad)
        got = {r.seq: r for r in reader}
        lost = set(good) - set(got)
        assert len(lost) <= 1, (off, lost)
        assert all(good[s] == r for s, r in got.items()), f"byte {off}: a record read back changed"
        assert {s for d in reader.damages for s in d.lost} == lost, (off, [d.describe() for d in reader.damages])
        assert reader.damages, f"byte {off}: a changed byte went unnoticed"
        assert reader.next_seq > max(good), f"byte {off}: sequence number {reader.next_seq} would be reused"


def test_a_log_of_the_previous_format_is_read_and_said_so(tmp_path: Path) -> None:
    """A format-1 log (no checksums) recovers in a core of today, which says so and appends
    format-2 records after it; the whole file reads back."""
    import struct

    import msgpack

    from robo_comp.protocol.logfile import LogReader

    state = tmp_path / "state"
    state.mkdir()
    old = [{"format": "robo_comp-eventlog", "version": 1, "started": 1000.0}]
    for i, rid in enumerate(("red-1", "red-2")):
        old.append({"seq": 1 + i, "t": 1000.0 + i, "topic": "robot.registered", "team": "red",
                    "data": {"tag": 101 + i, "team": "red", "robot_id": rid, "x": 1.0, "y": 1.0, "heading": 0.0}})
    old.append({"seq": 3, "t": 1003.0, "topic": "score.change", "team": "red",
                "data": {"team": "red", "points": -1, "kind": "penalty", "reason": "old foul", "t": 0.0}})
    with open(state / "events.log", "wb") as f:
        for obj in old:
            blob = msgpack.packb(obj, use_bin_type=True)
            f.write(struct.pack(">I", len(blob)) + blob)
    proc = start_core(state, "--heartbeat", "0.2", "--teams", "red,blue")
    match = CoreHandle(state, None, proc)
    try:
        ref = match.referee()
        rec = ref.request("stats")["recovered"]
        assert rec["legacy_records"] == 3 and rec["damage"] is None, rec
        assert sorted(r["tag"] for r in ref.robots()) == [101, 102]
        assert [ln["reason"] for ln in ref.score()["lines"]] == ["old foul"]
        assert "previous format" in match.log_tail()
        ref.request("penalty", team="red", points=-1, reason="new foul")
        _kill9_between_writes(proc)
        reader = LogReader(state / "events.log")
        recs = list(reader)
        assert not reader.damages and reader.legacy == 3
        assert [r.seq for r in recs] == list(range(1, len(recs) + 1))
        assert "new foul" in {r.data.get("reason") for r in recs if r.topic == "score.change"}
        match.proc = start_core(state)  # format 1 then 2 in one file: read again, nothing lost
        rec = match.referee().request("stats")["recovered"]
        assert rec["legacy_records"] == 3 and rec["damage"] is None and rec["events"] == len(recs) + 0, rec
    finally:
        match.close()


# ---------------------------------------------------------------------------------------------
# Match time that only the match moves (issue 32).


def test_the_match_clock_ignores_wall_clock_steps_across_restarts(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The core under libfaketime: a scored match runs, the machine's clock steps +2 h, the core is
    killed and restarted, the clock steps -1 h, killed and restarted again. The match clock stays
    within 1 s of the time the match really ran (the outage rule 'pause': downtime not counted)."""
    lib = _libfaketime()
    if lib is None:
        pytest.skip("libfaketime is not installed (Debian package faketime; .ci/run installs it)")
    wall = tmp_path / "faketime.rc"
    wall.write_text("+0\n")
    # an NTP step moves the wall clock only: the monotonic clocks are left alone
    monkeypatch.setenv("LD_PRELOAD", lib)
    monkeypatch.setenv("FAKETIME_TIMESTAMP_FILE", str(wall))
    monkeypatch.setenv("FAKETIME_NO_CACHE", "1")
    monkeypatch.setenv("FAKETIME_DONT_FAKE_MONOTONIC", "1")
    from robo_comp.world import scenario as scen

    demo = Path(scen.__file__).parent / "scenarios" / "demo_room.toml"
    state = tmp_path / "state"
    proc = start_core(state, "--heartbeat", "0.2", "--scenario", str(demo))
    match = CoreHandle(state, None, proc)
    ran = 0.0
    try:
        match.referee().match("start")
        since = time.monotonic()
        for step in ("+7200", "-3600"):
            time.sleep(1.0)
            wall.write_text(step + "\n")
            time.sleep(0.5)  # the core writes events stamped with the stepped clock
            proc.kill()
            proc.wait()
            ran += time.monotonic() - since
            time.sleep(1.0)  # the outage: not match time under the default rule
            match.proc = proc = start_core(state)
            since = time.monotonic()
            st = match.referee().score()
            assert st["phase"] == "running", st
            assert abs(st["elapsed"] - ran) < 1.0, (step, st, ran)
            assert st["outage"] == "pause"
        rec = match.referee().request("stats")["recovered"]
        assert "'pause'" in rec["clock"], rec
    finally:
        match.close()


def test_practice_keeps_its_clock_and_the_referee_chooses_the_outage_rule(tmp_path: Path) -> None:
    """A practice match (no phases) keeps its clock across kill -9; with the outage rule 'count'
    the time the core was down is match time, with 'pause' (the default) it is not."""
    state = tmp_path / "state"
    proc = start_core(state, "--heartbeat", "0.2", "--teams", "red")
    match = CoreHandle(state, None, proc)
    try:
        ref = match.referee()
        st = ref.score()
        assert st["phase"] == "running" and st["outage"] == "pause", st
        time.sleep(1.5)
        before = ref.score()["elapsed"]
        proc.kill()
        proc.wait()
        time.sleep(2.0)
        match.proc = proc = start_core(state)
        after = match.referee().score()["elapsed"]
        assert before - 0.3 <= after < before + 1.0, (before, after)  # not 0, and the outage not counted
        ctl = subprocess.run([sys.executable, "-m", "robo_comp.cli", "ctl", "--core", str(state), "--token-file",
                              str(state / "referee.token"), "match", "outage", "--rule", "count"],
                             capture_output=True, text=True, timeout=60)
        assert "a core outage: the clock counts it" in ctl.stdout, ctl
        assert match.referee().score()["outage"] == "count"
        time.sleep(0.5)
        before = match.referee().score()["elapsed"]
        proc.kill()
        proc.wait()
        time.sleep(2.0)
        match.proc = proc = start_core(state)
        st = match.referee().score()
        assert st["outage"] == "count" and st["elapsed"] >= before + 2.0, (before, st)
        rec = match.referee().request("stats")["recovered"]
        assert "'count'" in rec["clock"] and "boot-time clock" in rec["clock"], rec
        with pytest.raises(FieldError, match="'pause'"):
            match.referee().match("outage", rule="sometimes")
    finally:
        match.close()


# ---------------------------------------------------------------------------------------------
# A host's results are not lost to an outage (issue 32).


def test_a_task_done_while_the_core_is_down_is_sent_again_and_taken_once(tmp_path: Path) -> None:
    """The core is frozen right after giving a short task, the robot finishes it (its task.done
    finds no core), the core is killed and restarted: the host sends the result again with its
    registration, and the log has the task done once, with its result, not cancelled."""
    from robo_comp.launch import start_robots

    state = tmp_path / "state"
    proc = start_core(state, "--heartbeat", "1.0", "--teams", "red")  # the host holds after 3 s of silence
    match = CoreHandle(state, None, proc)
    try:
        match.procs.append(start_robots(state, "red", 1, "--speed", "4"))
        red = match.client("red")
        row = wait_robots(red, 1)[0]
        tag, x, y = row["tag"], int(row["x"]), int(row["y"])
        goal = [x + 1 if x < 5 else x - 1, y]  # a neighbouring cell: a fraction of a second away
        tid = red.give(tag, "goTo", goal)["task_id"]
        os.kill(proc.pid, signal.SIGSTOP)  # the task went out with the reply; its task.done finds no core
        host_log = state / "robots-red.log"
        t_end = time.monotonic() + 20
        while "lost the core" not in host_log.read_text(errors="replace"):  # 3 s: long after the task ended
            assert time.monotonic() < t_end, host_log.read_text()[-2000:]
            time.sleep(0.1)
        proc.kill()
        proc.wait()
        assert not [e for e in match.logged_events("task.done") if e["data"]["task_id"] == tid]
        match.proc = start_core(state)
        red = match.client("red")

        def finished() -> dict[str, Any] | None:
            return next((t for t in red.tasks(tag)["done"] if t["task_id"] == tid), None)

        task = wait_for(finished, 30, "the task's result after the restart")
        assert task["ok"] is True and task["state"] == "done", task
        done = [e["data"] for e in match.logged_events("task.done") if e["data"]["task_id"] == tid]
        assert len(done) == 1 and done[0]["ok"] and done[0]["state"] == "done", done
        assert "restarted" not in done[0]["status"]
    finally:
        match.close()


def test_task_done_is_idempotent_and_a_task_lost_on_the_way_is_handed_over_again(core: CoreHandle) -> None:
    """Raw frames: a task.done sent twice is taken once (the second answer says so); a host that
    re-registers without the task it never got is given it again; a host that restarted gets
    its task cancelled with a sentence that says so."""
    from test_hostile_clients import Peer, raw_host, router

    host, tag = raw_host(core, "red", "r1")
    red = core.client("red")
    tid = red.give(tag, "goTo", [3, 3])["task_id"]
    body = {"tag": tag, "task_id": tid, "ok": True, "status": "arrived", "result": {"reached": [3, 3]}}
    first = host.own("task.done", body)
    again = host.own("task.done", body)
    assert first["ok"] and not first["body"].get("duplicate"), first
    assert again["ok"] and again["body"]["duplicate"] is True, again
    assert [e["data"]["task_id"] for e in core.logged_events("task.done")].count(tid) == 1
    # the same result again with a registration (a reconnect whose answer was lost): taken once too
    second = red.give(tag, "goTo", [4, 4])["task_id"]
    host.close()  # the old connection is gone (a host keeps its robots until then: E_HELD)
    wait_for(lambda: red.monitor(tag)["status"] == "lost", 10, "the robot lost with its old connection")
    back = Peer(router(core), token=core.host_token("red"))
    assert back.own("hello", {"token": core.host_token("red"), "client": "robots"})["ok"]
    reg = back.own("register", {"token": core.host_token("red"), "robot_id": "r1", "fresh": False, "done": body,
                                "tasks": [{"name": "goTo", "args": [{"name": "x", "type": "int"},
                                                                    {"name": "y", "type": "int"}]}]})
    assert reg["ok"] and reg["body"]["task"]["task_id"] == second, reg  # never got it: handed over again
    assert [e["data"]["task_id"] for e in core.logged_events("task.done")].count(tid) == 1
    assert red.tasks(tag)["current"]["task_id"] == second
    # a host that restarted (fresh) and runs nothing: the task is cancelled, saying why
    back.close()
    wait_for(lambda: red.monitor(tag)["status"] == "lost", 10, "the robot lost with its old connection")
    fresh = Peer(router(core), token=core.host_token("red"))
    assert fresh.own("hello", {"token": core.host_token("red"), "client": "robots"})["ok"]
    reg = fresh.own("register", {"token": core.host_token("red"), "robot_id": "r1", "tasks": []})
    assert reg["ok"] and reg["body"]["task"] is None, reg
    cancelled = next(t for t in red.tasks(tag)["done"] if t["task_id"] == second)
    assert cancelled["state"] == "cancelled" and "host restarted" in cancelled["status"], cancelled
    fresh.close()


# ---------------------------------------------------------------------------------------------
# A restart on a full disk (issue 32).


def test_a_core_restarted_on_a_full_disk_says_so_waits_and_comes_up_by_itself(small_disk: Path, tmp_path: Path) -> None:
    """The core is killed, its disk filled to the last byte, the core started again: it says what
    is full and how much room it needs (no traceback) and waits; once space is freed it comes up
    by itself with the match. With ``--on-full-disk exit`` it exits with the sentence instead."""
    state = small_disk / "state"
    proc = start_core(state, "--heartbeat", "0.2", "--teams", "red")
    match = CoreHandle(state, None, proc)
    try:
        match.referee().request("penalty", team="red", points=-1, reason="before the disk filled")
        proc.kill()
        proc.wait()
        (state / "core.json").unlink()
        filler = fill(small_disk)
        err = tmp_path / "core.err"  # beside the full disk, not on it
        with open(err, "wb") as f:
            proc = subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "core", "--state", str(state)],
                                    stdout=subprocess.DEVNULL, stderr=f, stdin=subprocess.DEVNULL)
        match.proc = proc
        t_end = time.monotonic() + 30
        while "is full" not in err.read_text():
            assert proc.poll() is None, err.read_text()
            assert time.monotonic() < t_end, err.read_text()
            time.sleep(0.1)
        said = err.read_text()
        assert f"mounted on {small_disk}" in said and "needs at least 1.0 MiB" in said, said
        assert "starts by itself once there is room" in said and "Traceback" not in said, said
        assert proc.poll() is None and not (state / "core.json").exists()
        filler.unlink()
        t_end = time.monotonic() + 30
        while not (state / "core.json").exists():
            assert proc.poll() is None, err.read_text()
            assert time.monotonic() < t_end, err.read_text()
            time.sleep(0.1)
        lines = match.referee().score()["lines"]
        assert [ln["reason"] for ln in lines] == ["before the disk filled"]
        assert "there is room again" in err.read_text() and "Traceback" not in err.read_text()
        proc.kill()
        proc.wait()
        filler = fill(small_disk)
        out = subprocess.run([sys.executable, "-m", "robo_comp.cli", "core", "--state", str(state),
                              "--on-full-disk", "exit"], capture_output=True, text=True, timeout=60)
        assert out.returncode == 2, out
        assert "is full" in out.stderr and "start the core again" in out.stderr and "Traceback" not in out.stderr
        filler.unlink()
    finally:
        match.close()
