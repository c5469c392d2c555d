"""The sandbox for team code: templates, contract, versions, robot API, cancel, respawn."""
from __future__ import annotations

import hashlib
import os
import pathlib
import time

import pytest

from robo_comp.errors import BadTaskError, NotYoursError, UploadError
from robo_comp.sandbox import policy
from robo_comp.sandbox.contract import BUILTIN_TASKS
from robo_comp.sandbox.parent import (
    PENDING, Limits, LogLine, Loaded, RpcCall, Sandbox, SandboxStopped, TaskDone, TaskFailed,
    poll_many,
)
from robo_comp.sandbox.child import RECV_BYTES, FrameError, FrameReader, pack

ROOT = pathlib.Path(__file__).parent.parent
SQUARE = (ROOT / "team_templates" / "extensions" / "square.py").read_text()
WANDER = (ROOT / "team_templates" / "extensions" / "wander_code.py").read_text()
FAST = Limits(cpu_seconds=1, memory_mib=192, wall_seconds=1.0, load_seconds=1.5,
              init_seconds=0.5, cancel_grace=0.3, output_bytes=4096, max_runs=3, max_respawns=5)


def module(name: str, body: str, version: str = "1", kind: str = "extension",
           tasks: str = '"work": {"args": []}') -> str:
    """A small valid team module with ``body`` appended."""
    return (f'MANIFEST = {{"name": "{name}", "version": "{version}", "kind": "{kind}", '
            f'"tasks": {{{tasks}}}}}\n\n{body}\n')


class Host:
    """A recording handler: answers at once, or PENDING for names in ``pending``."""

    def __init__(self, pending: tuple[str, ...] = ()) -> None:
        self.calls: list[tuple[int, str, list]] = []
        self.pending = pending
        self.refuse: dict[str, str] = {}

    def __call__(self, tag: int, name: str, args: list):
        self.calls.append((tag, name, args))
        if name in self.refuse:
            raise BadTaskError(self.refuse.pop(name))
        if name in self.pending:
            return PENDING
        if name == "position":
            return [5, 6, 90]
        return True


def until(sb: Sandbox, pred, timeout: float = 5.0) -> list:
    """Poll ``sb`` until a record satisfies ``pred``; return all records seen."""
    seen = []
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        recs = sb.poll(0.05)
        seen += recs
        if any(pred(r) for r in recs):
            return seen
    raise AssertionError(f"timeout; saw {seen}")


@pytest.fixture(scope="module")
def host():
    return Host()


@pytest.fixture(scope="module")
def sb(host):
    box = Sandbox("red", [1, 2], host, FAST)
    yield box
    box.close()


# ------------------------------------------------------------------ templates
def test_square_template(sb, host):
    t0 = time.perf_counter()
    info = sb.load("square.py", SQUARE)
    assert time.perf_counter() - t0 < 2.0
    assert (info.name, info.version, info.kind) == ("square", "1.0", "extension")
    assert info.sha256 == hashlib.sha256(SQUARE.encode()).hexdigest()
    adv = sb.advertised_tasks()["square"]
    assert adv["args"] == [{"name": "side", "type": "int",
                            "description": "side length in cells (1-50)"}]
    assert adv["module"] == "square" and adv["replaces_builtin"] is False
    host.calls.clear()
    rec = sb.run_task(1, "square", [3])
    assert isinstance(rec, TaskDone) and rec.result == [5, 6, 90] and rec.task == "square"
    assert [c[1] for c in host.calls] == ["move", "turn"] * 4 + ["position"]
    assert all(c[0] == 1 for c in host.calls)
    assert host.calls[0][2] == [3] and host.calls[1][2] == [90]
    logs = [r for r in sb.poll(0.05) if isinstance(r, LogLine)]
    assert any("square extension ready" in r.text for r in logs)


def test_square_argument_errors(sb):
    with pytest.raises(BadTaskError):
        sb.start_task(1, "square", ["three"])
    with pytest.raises(BadTaskError):
        sb.start_task(1, "square", [])
    with pytest.raises(BadTaskError):
        sb.start_task(1, "no_such_task", [])
    with pytest.raises(NotYoursError):
        sb.start_task(99, "square", [2])
    rec = sb.run_task(2, "square", [0])  # team code validates too
    assert isinstance(rec, TaskFailed) and rec.reason == "error"
    assert "square.py:" in rec.message and "side must be between" in rec.message
    assert rec.line is not None


def test_wander_code_replaces_builtin(host):
    with Sandbox("green", [3], host, FAST) as box:
        info = box.load("wander_code.py", WANDER)
        assert info.kind == "code" and info.replaces == ["goTo"]
        assert box.advertised_tasks()["goTo"]["replaces_builtin"] is True
        host.calls.clear()
        host.refuse["go_to"] = "cell (5, 8) is a wall"  # the detour is refused once
        rec = box.run_task(3, "goTo", [5, 6])
        assert isinstance(rec, TaskDone), rec
        names = [c[1] for c in host.calls]
        assert names == ["position", "go_to", "go_to", "position"]
        assert host.calls[2][2] == [5, 6]
        text = "".join(r.text for r in box.poll(0.05) if isinstance(r, LogLine))
        assert "detour refused (go_to: cell (5, 8) is a wall)" in text


def test_extension_may_not_replace_builtin(sb):
    src = module("sneaky", "def goTo(robot, x, y):\n    return 1",
                 tasks='"goTo": {"args": [{"name": "x", "type": "int"}, {"name": "y", "type": "int"}]}')
    with pytest.raises(UploadError, match=r"sneaky.py: conflict: an extension may not replace"):
        sb.load("sneaky.py", src)
    assert "goTo" in BUILTIN_TASKS


# ------------------------------------------------------------------ versions and atomicity
def test_versions_replace_and_unload(sb):
    v1 = module("ver", "def work(robot):\n    return 'v1'")
    v2 = module("ver", "def work(robot):\n    return 'v2'", version="2")
    sb.load("ver.py", v1)
    assert sb.run_task(1, "work").result == "v1"
    rid = sb.begin_load("ver.py", v2)
    recs = until(sb, lambda r: isinstance(r, Loaded) and r.load_id == rid)
    loaded = [r for r in recs if isinstance(r, Loaded)][-1]
    assert loaded.previous == "1" and loaded.module.version == "2"
    assert sb.run_task(1, "work").result == "v2"
    mods = {m.name: m for m in sb.modules()}
    assert mods["ver"].version == "2"
    assert mods["ver"].sha256 == hashlib.sha256(v2.encode()).hexdigest()
    assert sb.unload("ver") is True
    until(sb, lambda r: type(r).__name__ == "Unloaded")
    assert "work" not in sb.advertised_tasks()
    with pytest.raises(BadTaskError):
        sb.start_task(1, "work")
    assert sb.unload("ver") is False


def test_failed_replacement_keeps_previous(sb):
    good = module("keep", "def work(robot):\n    return 'good'")
    bad = module("keep", "def init(robot):\n    raise ValueError('boom')\n\n"
                         "def work(robot):\n    return 'bad'", version="2")
    sb.load("keep.py", good)
    with pytest.raises(UploadError) as ei:
        sb.load("keep2.py", bad)
    msg = str(ei.value)
    assert msg.startswith("keep2.py:") and ": init: " in msg and "ValueError: boom" in msg
    assert ei.value.details["rule"] == "init" and ei.value.details["line"] == 4
    assert ei.value.code == "E_UPLOAD"
    assert sb.run_task(1, "work").result == "good"
    assert {m.name: m.version for m in sb.modules()}["keep"] == "1"
    sb.unload("keep")


def test_conflicting_task_names(sb):
    sb.load("one.py", module("one", "def shared(robot):\n    return 1",
                             tasks='"shared": {"args": []}'))
    with pytest.raises(UploadError, match=r"conflict: task 'shared' is already provided by module 'one'"):
        sb.load("two.py", module("two", "def shared(robot):\n    return 2",
                                 tasks='"shared": {"args": []}'))
    sb.unload("one")


@pytest.mark.parametrize("file,src,pattern", [
    ("syn.py", "MANIFEST = {\ndef x(:\n", r"^syn.py:\d+: syntax: "),
    ("../evil.py", "x = 1", r"filename: "),
    ("big.py", "x = 1\n" * 20000, r"^big.py: size: the source is \d+ bytes, the limit is 60000"),
    ("noman.py", "def work(robot):\n    return 1\n", r"^noman.py:1: manifest: the module declares no MANIFEST"),
    ("kw.py", module("kw", "def work(robot, *rest):\n    return 1"), r"^kw.py:3: signature: def work: no \*args"),
    ("badinit.py", module("bi", "def init(robot, extra):\n    pass\n\ndef work(robot):\n    return 1"),
     r"^badinit.py:3: signature: init must be declared as def init\(robot\)"),
    ("crash.py", module("cr", "x = 1 / 0\n\ndef work(robot):\n    return 1"),
     r"^crash.py:3: module: running the module body failed: crash.py:3: `x = 1 / 0`: ZeroDivisionError"),
])
def test_contract_errors_name_file_line_rule(sb, file, src, pattern):
    with pytest.raises(UploadError, match=pattern):
        sb.load(file, src)


# ------------------------------------------------------------------ robot API and the host side
def test_pending_resolve_and_reject_without_wall_clock():
    host = Host(pending=("move",))
    src = module("pend", "def work(robot):\n    first = robot.move(2)\n    try:\n"
                         "        robot.move(3)\n    except RobotError as e:\n"
                         "        return [first, str(e)]\n    return 'no error'")
    with Sandbox("red", [1], host, FAST) as box:
        box.load("pend.py", src)
        rid = box.start_task(1, "work")
        end = time.monotonic() + 3
        while len(host.calls) < 1 and time.monotonic() < end:
            box.poll(0.02)
        assert box.deadline() is None  # waiting on the host: no wall clock
        time.sleep(FAST.wall_seconds + 0.2)  # longer than the wall limit
        assert box.poll(0.0) == []
        call_id = max(box._calls)
        box.resolve(call_id, {"moved": 2})
        while len(host.calls) < 2 and time.monotonic() < end:
            box.poll(0.02)
        box.reject(max(box._calls), "blocked by a wall")
        recs = until(box, lambda r: isinstance(r, TaskDone) and r.run_id == rid)
        done = [r for r in recs if isinstance(r, TaskDone)][0]
        assert done.result == [{"moved": 2}, "move: blocked by a wall"]


def test_rpc_records_without_handler():
    src = module("nh", "def work(robot):\n    return robot.sense()")
    with Sandbox("red", [4], None, FAST) as box:
        box.load("nh.py", src)
        rid = box.start_task(4, "work")
        recs = until(box, lambda r: isinstance(r, RpcCall))
        call = [r for r in recs if isinstance(r, RpcCall)][0]
        assert (call.run_id, call.tag, call.name, call.args) == (rid, 4, "sense", [])
        box.resolve(call.call_id, [1.5, 2.5])
        recs = until(box, lambda r: isinstance(r, TaskDone))
        assert [r for r in recs if isinstance(r, TaskDone)][0].result == [1.5, 2.5]


def test_cancel_pending_call_raises_taskcancelled():
    host = Host(pending=("move",))
    src = module("cx", "def work(robot):\n    try:\n        robot.move(5)\n    finally:\n"
                       "        robot.log('cleanup ran')")
    with Sandbox("red", [1], host, FAST) as box:
        box.load("cx.py", src)
        rid = box.start_task(1, "work")
        end = time.monotonic() + 3
        while not host.calls and time.monotonic() < end:
            box.poll(0.02)
        assert box.cancel(rid) is True
        recs = until(box, lambda r: isinstance(r, TaskFailed))
        failed = [r for r in recs if isinstance(r, TaskFailed)][0]
        assert failed.reason == "cancelled"
        assert any("cleanup ran" in r.text for r in recs if isinstance(r, LogLine))
        assert not any(isinstance(r, SandboxStopped) for r in recs)


def test_cancel_interrupts_computing_task():
    src = module("spin", "def work(robot):\n    n = 0\n    while True:\n        n = n + 1")
    with Sandbox("red", [1], Host(), FAST) as box:
        box.load("spin.py", src)
        pid = box.pid
        rid = box.start_task(1, "work")
        box.poll(0.1)
        t0 = time.monotonic()
        box.cancel(rid)
        recs = until(box, lambda r: isinstance(r, TaskFailed))
        assert time.monotonic() - t0 < FAST.cancel_grace
        assert [r.reason for r in recs if isinstance(r, TaskFailed)] == ["cancelled"]
        assert box.pid == pid  # no kill was needed


def test_calls_for_removed_robot_are_refused():
    host = Host()
    src = module("tg", "def work(robot):\n    robot.move(1)\n    return robot.move(1)")
    with Sandbox("red", [1, 2], host, FAST) as box:
        box.load("tg.py", src)
        host.pending = ("move",)
        rid = box.start_task(2, "work")
        end = time.monotonic() + 3
        while not host.calls and time.monotonic() < end:
            box.poll(0.02)
        box.remove_tag(2)
        box.resolve(max(box._calls), True)
        recs = until(box, lambda r: isinstance(r, TaskFailed) and r.run_id == rid)
        failed = [r for r in recs if isinstance(r, TaskFailed)][0]
        assert "robot 2 is not one of team red's robots" in failed.message
        assert [c[0] for c in host.calls] == [2]


def test_two_robots_run_concurrently():
    host = Host(pending=("move",))
    with Sandbox("red", [1, 2], host, FAST) as box:
        box.load("square.py", SQUARE)
        runs = {box.start_task(1, "square", [1]), box.start_task(2, "square", [2])}
        done = {}
        end = time.monotonic() + 10
        while len(done) < 2 and time.monotonic() < end:
            for r in box.poll(0.02):
                if isinstance(r, TaskDone):
                    done[r.run_id] = r
            for call_id in list(box._calls):  # the "simulation": finish every movement
                box.resolve(call_id, True)
        assert set(done) == runs
        moves = [c for c in host.calls if c[1] == "move"]
        assert sorted(c[0] for c in moves) == [1] * 4 + [2] * 4


COUNTED = module("ct", """
def work(robot, n):
    for i in range(n):
        tag, k = robot.position()
        if tag != robot.tag or k != i:
            raise ValueError(f"robot {robot.tag} got the answer {[tag, k]} to its call {i}")
    return n
""", tasks='"work": {"args": [{"name": "n", "type": "int"}]}')


def test_answers_reach_their_own_run_when_runs_call_at_once():
    """Three runs calling in tight loops at once: each answer reaches the worker that made the
    call, in order (the waiting workers take turns reading the answers' socket, and one reads the
    others' answers for them: sandbox/child.py, _Replies)."""
    counts: dict[int, int] = {}

    def handler(tag: int, name: str, args: list) -> list[int]:
        counts[tag] = counts.get(tag, -1) + 1
        return [tag, counts[tag]]

    with Sandbox("red", [1, 2, 3], handler, FAST) as box:
        box.load("ct.py", COUNTED)
        runs = {box.start_task(tag, "work", [400]): tag for tag in (1, 2, 3)}
        done: dict[int, TaskDone | TaskFailed] = {}
        end = time.monotonic() + 60
        while len(done) < 3 and time.monotonic() < end:
            for r in box.poll(0.05):
                if isinstance(r, (TaskDone, TaskFailed)):
                    done[r.run_id] = r
        assert {rid: getattr(r, "result", r) for rid, r in done.items()} == dict.fromkeys(runs, 400)
        assert counts == {1: 399, 2: 399, 3: 399}


def test_answers_the_child_has_no_room_for_wait_and_go_out_in_order():
    """The answers' socket full (the child not reading): answers queue in the parent, deadline()
    asks the host loop back within REPLY_RETRY, and they go out whole and in order once there is
    room (real sockets; no child process)."""
    import socket as _socket

    from robo_comp.sandbox.parent import REPLY_RETRY, _Run

    box = Sandbox("red", [1], Host(), FAST, start=False)
    ours, theirs = _socket.socketpair()
    ours.setblocking(False)
    box._rsock = ours
    box._runs[1] = _Run(1, "task", 1, "work", None, "")
    big = "x" * 60_000
    try:
        for c in range(1, 41):
            box._calls[c] = 1
            box._answer(c, ok=True, value=[c, big])
        assert box._rout  # more than the socket holds
        due = box.deadline()
        assert due is not None and due <= time.monotonic() + REPLY_RETRY
        reader, got = FrameReader(1 << 20), []
        while len(got) < 40:
            try:
                got += reader.feed(theirs.recv(1 << 16))
            except BlockingIOError:
                pass
            box.check_timers()
            theirs.setblocking(not box._rout)
        assert [m["v"][0] for m in got] == list(range(1, 41)) and all(m["v"][1] == big for m in got)
        assert not box._rout and box.deadline() == box._runs[1].deadline  # only the run's own clock now
    finally:
        ours.close()
        theirs.close()


def test_respawn_keeps_good_modules():
    src = module("loop", "def spin(robot):\n    while True:\n        pass",
                 tasks='"spin": {"args": []}')
    with Sandbox("red", [1], Host(), FAST) as box:
        box.load("square.py", SQUARE)
        box.load("loop.py", src)
        old_pid = box.pid
        rid = box.start_task(1, "spin")
        recs = until(box, lambda r: isinstance(r, SandboxStopped), timeout=5)
        failed = [r for r in recs if isinstance(r, TaskFailed) and r.run_id == rid][0]
        assert failed.reason == "limit"
        assert "wall-clock limit (1 s) exceeded" in failed.message or "CPU time limit (1 s)" in failed.message
        stop = [r for r in recs if isinstance(r, SandboxStopped)][0]
        assert stop.respawned and stop.reason in ("wall", "cpu")
        rec = box.run_task(1, "square", [1])  # held until the replays are loaded
        assert isinstance(rec, TaskDone)
        assert box.pid != old_pid
        assert sorted(m.name for m in box.modules()) == ["loop", "square"]


def test_oversize_message_from_child_stops_sandbox():
    src = module("big", "def work(robot):\n    return robot.radio(2, 'x' * 3000)")
    with Sandbox("red", [1], Host(), FAST) as box:
        box.load("big.py", src)
        box._reader.cap = 1000  # pretend the child ignored its own cap
        box.start_task(1, "work")
        recs = until(box, lambda r: isinstance(r, SandboxStopped))
        stop = [r for r in recs if isinstance(r, SandboxStopped)][0]
        assert stop.reason == "message" and "message too large" in stop.message


def test_print_goes_to_team_log_capped():
    src = module("pr", "def work(robot):\n    print('hello', 42)\n    return 1")
    with Sandbox("red", [1], Host(), FAST) as box:
        box.load("pr.py", src)
        rid = box.start_task(1, "work")
        recs = until(box, lambda r: isinstance(r, TaskDone))
        lines = [r for r in recs if isinstance(r, LogLine)]
        assert lines and lines[0].text == "hello 42\n" and lines[0].stream == "print"
        assert lines[0].run_id == rid and lines[0].tag == 1


def test_poll_many_and_close_kills_child():
    boxes = [Sandbox(f"t{i}", [i], Host(), FAST) for i in range(2)]
    for b in boxes:
        b.begin_load("square.py", SQUARE)
    got = []
    end = time.monotonic() + 5
    while len(got) < 2 and time.monotonic() < end:
        got += [r for _, r in poll_many(boxes, 0.05) if isinstance(r, Loaded)]
    assert len(got) == 2
    pids = [b.pid for b in boxes]
    for b in boxes:
        b.close()
    for pid in pids:
        assert not os.path.exists(f"/proc/{pid}") or \
            open(f"/proc/{pid}/stat").read().split()[2] == "Z"


def test_frame_reader_caps_and_rejects_garbage():
    r = FrameReader(100)
    assert r.feed(pack({"t": "x", "v": [1, 2]})) == [{"t": "x", "v": [1, 2]}]
    with pytest.raises(FrameError, match=r"message too large \(200 bytes > 100 bytes\)"):
        FrameReader(100).feed((200).to_bytes(4, "big") + b"x")
    with pytest.raises(FrameError):
        FrameReader(100).feed((3).to_bytes(4, "big") + b"\x92\x01\x02")  # not a map
    with pytest.raises(TypeError):
        pack({"t": "x", "v": object()})


# ------------------------------------------------------------------ the policy itself (no child)
def run_policy(src: str) -> dict:
    glb = policy.make_globals("team.t")
    exec(policy.compile_team(src, "t.py"), glb)
    return glb


def test_policy_allows_normal_team_code():
    glb = run_policy(
        "import math\nfrom random import randint\n"
        "class Counter:\n    def __init__(self):\n        self.n = 0\n"
        "    def bump(self, k):\n        self.n = self.n + k\n        return self.n\n"
        "c = Counter()\nc.bump(2)\nc.bump(3)\n"
        "a, (b, d) = 1, [2, 3]\nsq = [x * x for x in range(4)]\ntotal = 0\n"
        "for i, v in enumerate(sq):\n    total += v\n"
        "label = f'{c.n!r:>4}|{math.floor(2.5)}' + ' %d' % 7\nr = randint(1, 6)\n"
        "d2 = {}\nd2['k'] = [1]\nd2['k'].append(2)\n")
    assert glb["c"].n == 5 and glb["total"] == 14 and glb["label"] == "   5|2 7"
    assert 1 <= glb["r"] <= 6 and glb["d2"] == {"k": [1, 2]}


@pytest.mark.parametrize("src,exc,pattern", [
    ("import math\nmath.pi = 3", TypeError, "read-only"),
    ("import os", ImportError, "import of 'os' is not allowed"),
    ("x = getattr(1, '__class__')", AttributeError, "invalid attribute name"),
    ("x = '{0}'.format(1)", AttributeError, "str.format"),
    ("x = type(int)", TypeError, "metaclass"),
    ("def f():\n    pass\nf.x = 1", TypeError, "read-only"),
])
def test_policy_refusals(src, exc, pattern):
    with pytest.raises(exc, match=pattern):
        run_policy(src)


def test_policy_compile_errors_have_line_and_rule():
    with pytest.raises(policy.PolicyError) as ei:
        policy.compile_team("x = 1\ny = x.__dict__\n", "t.py")
    assert ei.value.line == 2 and ei.value.rule == "policy"
    with pytest.raises(policy.PolicyError) as ei:
        policy.compile_team("x = (\n", "t.py")
    assert ei.value.rule == "syntax"


LOOP = module("lp", "def work(robot, n):\n    for i in range(n):\n        robot.sense()\n    return n",
              tasks='"work": {"args": [{"name": "n", "type": "int"}]}')


def test_the_call_limiter_never_paces_a_single_loop():
    """One run calling in a tight loop is never held back, whatever the CPU: the limiter's rate
    follows the fastest loop it has measured (``Limits.rpc_loops`` times its calls per second), so
    every turn of the loop earns more than the token it spends. A least rate of 50 calls/s and a
    burst of 1 show it (before, the fixed rate paced every loop faster than it: 500 calls took
    10 s here)."""
    host = Host()
    with Sandbox("red", [1], host, Limits(rpc_per_second=50.0, rpc_burst=1)) as box:
        box.load("lp.py", LOOP)
        rec = box.run_task(1, "work", [500])
        assert isinstance(rec, TaskDone) and rec.result == 500
        assert len(host.calls) == 500
        assert box.paced_calls == 0
        assert box.call_rate() == Limits().rpc_loops / box.fastest_loop > 50.0


def test_the_default_call_limiter_does_not_pace_a_loop():
    with Sandbox("red", [1], Host(), Limits()) as box:
        box.load("lp.py", LOOP)
        rec = box.run_task(1, "work", [3000])
        assert isinstance(rec, TaskDone) and rec.result == 3000
        assert box.paced_calls == 0


FLOOD_CALLS = 40
FLOOD = module("fl", """
def work(robot):
    # below the policy (the planted hole gives the real os): call frames written to the sandbox's
    # own socket, without waiting for any answer
    for fd in range(3, 32):
        try:
            if os.fstat(fd).st_mode & 0o170000 == 0o140000:  # the first socket: the one calls go on
                os.write(fd, FRAMES)
                break
        except OSError:
            pass
    return robot.sense()   # answered after the forged calls, which the limiter holds back
""")


def test_the_call_limiter_holds_back_a_flood():
    """Calls sent without waiting for their answers (forged by team code through the planted hole
    in the policy, written straight to the sandbox's socket) are held to the limiter's rate after
    the burst, answered later and never refused; and, sent together, they are no loop: the rate
    does not rise (docs/sandbox.md, "The call limiter")."""
    rate, burst = 100.0, 2
    frames = b"".join(pack({"t": "call", "c": 10**6 + i, "r": 2, "g": 1, "n": "sense", "a": []})
                      for i in range(FLOOD_CALLS))
    src = FLOOD.replace("def work", f"FRAMES = {frames!r}\n\n\ndef work", 1)
    seen: list[float] = []

    def handler(tag: int, name: str, args: list) -> bool:
        seen.append(time.monotonic())
        return True

    with Sandbox("red", [1], handler, Limits(rpc_per_second=rate, rpc_burst=burst, test_policy_hole=True)) as box:
        box.load("fl.py", src)
        rec = box.run_task(1, "work", timeout=30.0)
        assert rec is not None and rec.run_id == 2  # the run the frames name
        assert isinstance(rec, TaskDone) and rec.result is True, rec
        assert len(seen) == FLOOD_CALLS + 1  # every call answered, none refused
        assert box.paced_calls >= FLOOD_CALLS // 2
        assert box.fastest_loop == float("inf") and box.call_rate() == rate
        for k, t in enumerate(seen):  # the token bucket: never more than the burst plus the rate
            assert k + 1 <= burst + rate * (t - seen[0]) + 1



def test_calls_sent_without_waiting_do_not_raise_the_limiter_whatever_read_they_come_in():
    """A flood bigger than one read of the socket (64 KiB): the calls come in several reads, each
    after the answers to the calls of the read before had gone out, so a read alone cannot tell
    them from a loop's. Only a call that names the key of its run's last answer (which it can know
    only by reading that answer) counts as a turn of a loop: the rate stays where it was. (Before,
    the first call of a later read counted as a loop of some tens of microseconds: fastest_loop
    67 us, the rate 100 -> 30,000 calls a second.)"""
    rate, calls = 100.0, 200
    # the frames are made in team code (the module's source is at most 60 KB): each is one call
    # frame with its id (a msgpack uint32, 0xce and four bytes) changed
    frame = pack({"t": "call", "c": 10**6, "r": 2, "g": 1, "n": "sense", "a": ["x" * 1000]})
    at = frame.index(b"\xa1c\xce") + 2
    head, tail = frame[:at], frame[at + 5:]
    assert calls * len(frame) > 2 * RECV_BYTES
    src = FLOOD.replace("def work", f"HEAD = {head!r}\nTAIL = {tail!r}\nFRAMES = b''.join(\n"
                        f"    HEAD + b'\\xce' + (10**6 + i).to_bytes(4, 'big') + TAIL for i in range({calls}))"
                        "\n\n\ndef work", 1)
    seen: list[list] = []

    def handler(tag: int, name: str, args: list) -> bool:
        seen.append(args)
        return True

    with Sandbox("red", [1], handler, Limits(rpc_per_second=rate, rpc_burst=2 * calls,
                                             test_policy_hole=True)) as box:
        box.load("fl.py", src)
        rec = box.run_task(1, "work", timeout=30.0)
        assert isinstance(rec, TaskDone) and rec.result is True, rec
        assert len(seen) == calls + 1 and box.paced_calls == 0  # all within the burst, none refused
        assert box.fastest_loop == float("inf") and box.call_rate() == rate

def test_child_runs_under_limits():
    with Sandbox("red", [1], Host(), FAST) as box:
        box.load("square.py", SQUARE)  # ready and limited by now
        limits = open(f"/proc/{box.pid}/limits").read()
        status = open(f"/proc/{box.pid}/status").read()

    def row(name):
        return [ln for ln in limits.splitlines() if ln.startswith(name)][0].split()

    assert row("Max address space")[3] == str(192 * 1024 * 1024)
    assert row("Max file size")[3] == "0"
    assert row("Max core file size")[4] == "0"
    assert row("Max processes")[2] == "0"
    assert int(row("Max open files")[3]) <= 16
    if os.geteuid() == 0:
        assert "\nUid:\t65534\t65534\t65534\t65534" in status  # root dropped to nobody
    assert "\nNoNewPrivs:\t1" in status


def test_child_does_not_load_numpy():
    """numpy would eat a large part of RLIMIT_AS; the child must not import it."""
    with Sandbox("red", [1], Host(), FAST) as box:
        box.load("square.py", SQUARE)
        maps = open(f"/proc/{box.pid}/maps").read()
    assert "numpy" not in maps


KITCHEN_SINK = '''
import heapq
import math
import random

MANIFEST = {"name": "sink", "version": "1", "kind": "extension",
            "tasks": {"route": {"args": [{"name": "goal", "type": "point"}]}}}


class Planner:
    def __init__(self, walls):
        self.walls = set(walls)
        self.expanded = 0

    def neighbours(self, cell):
        x, y = cell
        for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            nxt = (x + dx, y + dy)
            if nxt not in self.walls and 0 <= nxt[0] < 8 and 0 <= nxt[1] < 8:
                yield nxt

    def astar(self, start, goal):
        frontier = [(0, start)]
        came = {start: None}
        cost = {start: 0}
        while frontier:
            _, cur = heapq.heappop(frontier)
            self.expanded = self.expanded + 1
            if cur == goal:
                break
            for nxt in self.neighbours(cur):
                c = cost[cur] + 1
                if nxt not in cost or c < cost[nxt]:
                    cost[nxt] = c
                    heapq.heappush(frontier, (c + abs(goal[0] - nxt[0]) + abs(goal[1] - nxt[1]), nxt))
                    came[nxt] = cur
        path, cur = [], goal
        while cur is not None:
            path.append(list(cur))
            cur = came[cur]
        return sorted(path, key=lambda p: cost[tuple(p)])


memo = {}


def route(robot, goal):
    random.seed("same every time")
    planner = Planner([(3, y) for y in range(7)])
    path = planner.astar((0, 0), tuple(goal))
    memo[len(memo)] = len(path)
    label = f"{len(path)} cells, {planner.expanded} expanded, r={random.randint(1, 6)}"
    return {"path": path, "label": label, "hyp": round(math.hypot(3, 4), 1), "calls": len(memo)}
'''


def test_real_team_code_runs_under_the_policy():
    with Sandbox("red", [1], Host(), FAST) as box:
        box.load("sink.py", KITCHEN_SINK)
        first = box.run_task(1, "route", [[7, 0]])
        second = box.run_task(1, "route", [[7, 0]])
    assert isinstance(first, TaskDone), first
    r = first.result
    assert r["path"][0] == [0, 0] and r["path"][-1] == [7, 0] and len(r["path"]) == 22
    assert r["hyp"] == 5.0 and r["calls"] == 1 and r["label"].startswith("22 cells")
    assert second.result["calls"] == 2  # module state persists between runs
    assert second.result["label"] == r["label"]  # random is seedable and deterministic


def test_cpu_limit_kill_is_named():
    # the wall limit far above the CPU limit: on a loaded machine the child gets a small share of a
    # core, and 1 s of CPU took more than 5 s of real time (the wall limit then fired first)
    limits = Limits(cpu_seconds=1, wall_seconds=60.0, memory_mib=192)
    src = module("burn", "def work(robot):\n    n = 0\n    while True:\n        n = n + 1")
    with Sandbox("red", [1], Host(), limits) as box:
        box.load("burn.py", src)
        rec = box.run_task(1, "work", timeout=90)
        assert isinstance(rec, TaskFailed) and rec.reason == "limit"
        assert rec.message.startswith("CPU time limit (1 s) exceeded") and "robot calls between them" in rec.message
        stops = [r for r in box.poll(0.05) if isinstance(r, SandboxStopped)]
        assert stops and stops[0].reason == "cpu" and stops[0].respawned
