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
from pathlib import Path

import pytest

from conftest import CoreHandle, next_event_where, wait_robots
from robo_comp.errors import StorageError, TimeoutError_
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
        match.robots("red", 2)
        red = match.client("red")
        ref = match.referee()
        ref.watch(True)
        rows = wait_robots(red, 2)
        a, b = rows[0]["tag"], rows[1]["tag"]
        acked = [red.give(a, "goTo", [8, 8])["task_id"]]
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
        # everything acknowledged is in the log (a core killed now recovers it), the stop too
        proc.kill()
        proc.wait()
        given = {e["data"]["task_id"] for e in match.logged_events("task.given")}
        assert set(acked) <= given, sorted(set(acked) - given)
        assert any(e["data"]["tag"] == b for e in match.logged_events("robot.stopped"))
        match.proc = start_core(state, "--heartbeat", "0.2", "--teams", "red,blue")
        recovered = match.client("referee").tasks(b)
        assert recovered["current"]["task_id"] == acked[-1] and recovered["queued"] == []  # the stop held
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
    rows = wait_robots(red, 2, timeout=20.0)
    assert sorted(r["tag"] for r in rows) == tags  # the same tags
    tasks = red.tasks(tags[0])
    assert given in {t["task_id"] for t in [*tasks["done"], *filter(None, [tasks["current"]]), *tasks["queued"]]}
    assert red.give(tags[1], "goTo", [3, 3])["task_id"] > given


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
