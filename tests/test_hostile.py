"""Hostile team modules (tests/hostile/*.py) against the real sandbox.

Each hostile file says in its header what must happen::

    # expect: upload | run      (refused by the contract, or stopped while running ``attack``)
    # match: <regex>            (the error message must match: it names the rule or the limit)
    # cancel-after: <seconds>   (optional: the host cancels the task after that time)

All cases run at the same time in one host loop (:func:`poll_many`), one sandbox each, next to
a bystander team whose ``square`` task must keep completing. Every hostile sandbox first loads
a benign ``probe`` module; after the attack (and any kill + respawn) ``probe`` must still run
and see an unpoisoned ``math`` — the robot keeps working with what it had.
"""
from __future__ import annotations

import math
import os
import pathlib
import re
import time

import pytest

from robo_comp.errors import UploadError
from robo_comp.sandbox.parent import (
    Limits, Loaded, LoadFailed, Sandbox, SandboxStopped, TaskDone, TaskFailed, poll_many,
)

HERE = pathlib.Path(__file__).parent
HOSTILE = sorted((HERE / "hostile").glob("*.py"))
SQUARE = (HERE.parent / "team_templates" / "extensions" / "square.py").read_text()
PWNED = pathlib.Path("/tmp/robo_comp_pwned")

LIMITS = Limits(cpu_seconds=1, memory_mib=192, wall_seconds=1.5, load_seconds=1.5,
                init_seconds=0.5, cancel_grace=0.3, output_bytes=8192, result_bytes=16384,
                max_runs=2, max_respawns=3)

PROBE = '''
import math
MANIFEST = {"name": "probe", "version": "1", "kind": "extension",
            "tasks": {"probe": {"args": [], "description": "health check"}}}

def probe(robot):
    return [math.pi, math.sqrt(16), robot.position()]
'''


def header(path: pathlib.Path) -> dict[str, str]:
    """The ``# key: value`` lines at the top of a hostile file."""
    out = {}
    for line in path.read_text().splitlines()[:6]:
        m = re.match(r"# ([a-z-]+): (.*)$", line)
        if m:
            out[m.group(1)] = m.group(2).strip()
    return out


def immediate(tag: int, name: str, args: list):
    """A host handler that answers every robot-API call at once."""
    return {"position": [1, 2, 0], "sense": [3.0, 4.0], "radio": True}.get(name, True)


class Case:
    """One hostile module driven through: probe load → hostile load → attack → probe run."""

    def __init__(self, path: pathlib.Path) -> None:
        self.path = path
        self.h = header(path)
        self.sb = Sandbox(f"evil-{path.stem}", [1], immediate, LIMITS)
        self.probe_load = self.sb.begin_load("probe.py", PROBE)
        self.hostile_load: int | None = None
        self.attack: int | None = None
        self.probe_run: int | None = None
        self.cancel_at: float | None = None
        self.upload_error: UploadError | None = None
        self.accepted = False
        self.attack_record: TaskDone | TaskFailed | None = None
        self.probe_record: TaskDone | TaskFailed | None = None
        self.stops: list[SandboxStopped] = []
        self.done = False

    def on(self, rec) -> None:
        sb = self.sb
        if isinstance(rec, SandboxStopped):
            self.stops.append(rec)
        elif isinstance(rec, Loaded) and rec.load_id == self.probe_load:
            self.hostile_load = sb.begin_load(self.path.name, self.path.read_text())
        elif isinstance(rec, LoadFailed) and rec.load_id == self.probe_load:
            self.upload_error = rec.error
            self.done = True
        elif isinstance(rec, (Loaded, LoadFailed)) and rec.load_id == self.hostile_load:
            if isinstance(rec, LoadFailed):
                self.upload_error = rec.error
                self.probe_run = sb.start_task(1, "probe", [])
            else:
                self.accepted = True
                self.attack = sb.start_task(1, "attack", [])
                if "cancel-after" in self.h:
                    self.cancel_at = time.monotonic() + float(self.h["cancel-after"])
        elif isinstance(rec, (TaskDone, TaskFailed)) and rec.run_id == self.attack:
            self.attack_record = rec
            self.cancel_at = None
            self.probe_run = sb.start_task(1, "probe", [])
        elif isinstance(rec, (TaskDone, TaskFailed)) and rec.run_id == self.probe_run:
            self.probe_record = rec
            self.done = True

    def tick(self, now: float) -> None:
        if self.cancel_at is not None and now >= self.cancel_at:
            self.cancel_at = None
            self.sb.cancel(self.attack)


@pytest.fixture(scope="module")
def outcomes():
    """Run every hostile case at once, with a bystander team; returns results by file stem."""
    if PWNED.exists():
        PWNED.unlink()
    cwd = os.getcwd()
    cases = {p.stem: Case(p) for p in HOSTILE}
    by_box = {c.sb: c for c in cases.values()}
    seen_tags: list[int] = []

    def bystander_handler(tag, name, args):
        seen_tags.append(tag)
        return [0, 0, 0] if name == "position" else True

    blue = Sandbox("blue", [7], bystander_handler, LIMITS)
    blue.load("square.py", SQUARE)
    blue_run = blue.start_task(7, "square", [2])
    blue_done, blue_failed = 0, []
    end = time.monotonic() + 35.0
    try:
        while time.monotonic() < end:
            pending = [c for c in cases.values() if not c.done]
            if not pending and blue_done >= 3:
                break
            boxes = [c.sb for c in pending] + [blue]
            for sb, rec in poll_many(boxes, timeout=0.05):
                if sb is blue:
                    if isinstance(rec, TaskDone) and rec.run_id == blue_run:
                        blue_done += 1
                        blue_run = blue.start_task(7, "square", [2])
                    elif isinstance(rec, TaskFailed):
                        blue_failed.append(rec)
                else:
                    by_box[sb].on(rec)
            now = time.monotonic()
            for c in pending:
                c.tick(now)
        yield {"cases": cases, "blue_done": blue_done, "blue_failed": blue_failed,
               "seen_tags": seen_tags, "cwd": cwd}
    finally:
        blue.close()
        for c in cases.values():
            c.sb.close()


def test_enough_hostile_modules():
    assert len(HOSTILE) >= 30


@pytest.mark.parametrize("path", HOSTILE, ids=lambda p: p.stem)
def test_hostile(path, outcomes):
    case: Case = outcomes["cases"][path.stem]
    assert case.done, f"case did not finish: accepted={case.accepted} attack={case.attack_record}"
    pattern = re.compile(case.h["match"])
    if case.h["expect"] == "upload":
        assert case.upload_error is not None, f"accepted a hostile module: {case.attack_record}"
        msg = str(case.upload_error)
        assert msg.startswith(path.name), msg  # names the file
        assert pattern.search(msg), msg
        assert case.upload_error.details.get("rule"), msg
    else:
        assert case.upload_error is None, str(case.upload_error)
        rec = case.attack_record
        assert isinstance(rec, TaskFailed), rec
        assert rec.reason in ("error", "limit", "cancelled"), rec
        assert pattern.search(rec.message), rec.message
    # the sandbox keeps working with what it had, and math was not poisoned
    probe = case.probe_record
    assert isinstance(probe, TaskDone), probe
    assert probe.result == [math.pi, 4.0, [1, 2, 0]]


def test_bystander_unharmed(outcomes):
    assert outcomes["blue_failed"] == []
    assert outcomes["blue_done"] >= 3
    assert set(outcomes["seen_tags"]) == {7}  # only its own robot


def test_host_process_unharmed(outcomes):
    assert math.pi == 3.141592653589793
    assert os.getcwd() == outcomes["cwd"]
    assert not PWNED.exists()
