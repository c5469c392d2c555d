"""Parent-side handle of a team sandbox: one child process per (team, robot host).

The robot host drives every :class:`Sandbox` from its single poll loop; nothing here starts a
thread. Per loop iteration the host

* waits on :meth:`Sandbox.fileno` for reading (and for writing if :meth:`Sandbox.wants_write`),
  with a timeout no later than :meth:`Sandbox.deadline`;
* calls :meth:`Sandbox.handle_readable` when readable, :meth:`Sandbox.handle_writable` when
  writable and :meth:`Sandbox.check_timers` when the deadline has passed (or simply
  :meth:`Sandbox.poll` which does all three without blocking);
* acts on the returned records (:class:`TaskDone`, :class:`TaskFailed`, :class:`LogLine`, ...).

Robot-API calls from team code reach ``handler(tag, name, args)``; it returns plain data, or
:data:`PENDING` and later :meth:`Sandbox.resolve` / :meth:`Sandbox.reject` the call. Without a
handler the calls come out as :class:`RpcCall` records.

Blocking conveniences (:meth:`Sandbox.load`, :meth:`Sandbox.run_task`, :func:`poll_many`) are
for tests, tools and simple hosts.
"""
from __future__ import annotations

import array
import collections
import contextlib
import math
import os
import select
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

import msgpack

from robo_comp.errors import BadTaskError, NotYoursError, UnavailableError, UploadError
from robo_comp.sandbox import contract, oswall
from robo_comp.sandbox.contract import BUILTIN_TASKS, ModuleInfo
from robo_comp.sandbox.child import (
    EXIT_INTERNAL, EXIT_MEMORY, EXIT_PROTOCOL, RECV_BYTES, FrameError, FrameReader, pack,
)

__all__ = [
    "PENDING", "Limits", "Sandbox", "poll_many",
    "Record", "Ready", "Drawing", "RpcCall", "LogLine", "TaskDone", "TaskFailed", "Loaded", "LoadFailed",
    "Unloaded", "SandboxStopped", "SandboxRestarted",
]


class _Pending:
    __slots__ = ()

    def __repr__(self) -> str:
        return "PENDING"


PENDING: Any = _Pending()
"""Return this from the handler when the answer comes later (``resolve``/``reject``)."""

#: Seconds between two tries to send answers the child's socket had no room for (then
#: :meth:`Sandbox.deadline` asks the host loop to come back that soon).
REPLY_RETRY = 0.001


@dataclass(frozen=True)
class Limits:
    """Limits of one sandbox. Times in seconds; wall-clock ones are enforced by the parent."""

    cpu_seconds: int = 2
    """CPU seconds team code may use without an answer from the parent (rlimit backstop)."""
    memory_mib: int = 256
    """Address-space limit of the child process."""
    wall_seconds: float = 2.0
    """Wall-clock time team code may compute between two robot-API calls (a *slice*)."""
    load_seconds: float = 3.0
    """Wall-clock time for checking a module and running its body (before ``init``)."""
    init_seconds: float = 1.0
    """Wall-clock time for ``init(robot)``, robot-API calls included."""
    cancel_grace: float = 0.5
    """How long a cancelled run may take to end before the child is killed."""
    message_bytes: int = 65536
    """Largest message either side may send."""
    result_bytes: int = 16384
    """Largest task result (encoded)."""
    output_bytes: int = 65536
    """Print/log output per run."""
    max_runs: int = 8
    """Concurrent runs (tasks + loads) per sandbox; one worker thread each."""
    spawn_seconds: float = 10.0
    """Time the child may take to start."""
    rpc_per_second: float = 20_000.0
    """The least rate of the call limiter (a token bucket per sandbox; 0 = no limiter): robot-API
    calls per second a sandbox may make, sustained, before any of its runs was measured. Calls over
    the rate are not refused, only answered later (docs/sandbox.md, "The call limiter")."""
    rpc_loops: float = 2.0
    """The limiter's rate follows the calls: it is at least this many times the calls per second
    of the fastest loop measured on the sandbox (the shortest time from one call of a run to its
    next). One run waits for each answer, so no run calls faster than that, and a single loop is
    never held back, on any CPU; all runs together get this many loops' worth."""
    rpc_burst: int = 2_000
    """Calls allowed at once before the rate applies."""
    nice: int = 10
    """Scheduling niceness added to the child: the host's loop wins over team code for CPU."""
    max_respawns: int = 5
    """Respawns allowed per ``respawn_window`` seconds; one more limit kill starts a cool-down."""
    respawn_window: float = 60.0
    cooldown_seconds: float = 60.0
    """How long a sandbox that hit its limits too often rests before it restarts by itself with
    the team's modules; doubled each time it happens again, up to ``max_cooldown``."""
    max_cooldown: float = 600.0
    test_policy_hole: bool = False
    """TESTS ONLY: team code finds the real ``os``, ``socket`` and ``ctypes`` modules among its
    builtins, a planted hole in the policy through which tests check what the OS layer still
    stops (sandbox/oswall.py, sandbox/sysfilter.py)."""

    def wire(self, seed: int) -> dict[str, Any]:
        """The subset the child needs."""
        return {"cpu_seconds": self.cpu_seconds, "memory_mib": self.memory_mib,
                "message_bytes": self.message_bytes, "result_bytes": self.result_bytes,
                "output_bytes": self.output_bytes, "workers": self.max_runs + 1, "seed": seed,
                "nice": self.nice, "test_policy_hole": self.test_policy_hole,
                "debug": os.environ.get("ROBO_COMP_SANDBOX_DEBUG") == "1"}


def keep_aslr() -> bool:
    """True when ``ROBO_COMP_SANDBOX_ASLR=1``: a replayable child keeps address-space
    randomisation on (tests check that a match replays without turning it off)."""
    return os.environ.get("ROBO_COMP_SANDBOX_ASLR") == "1"


# --------------------------------------------------------------------------- records
@dataclass
class Record:
    """Base of everything :meth:`Sandbox.handle_readable` and friends return."""


@dataclass
class Ready(Record):
    """The child is up (after a start or a respawn)."""

    pid: int


@dataclass
class RpcCall(Record):
    """A robot-API call the host must answer (only when the sandbox has no handler)."""

    call_id: int
    run_id: int
    tag: int
    name: str
    args: list


@dataclass
class LogLine(Record):
    """Team output: ``stream`` is ``print``, ``log`` (robot.log) or ``stdout``/``stderr``."""

    run_id: int | None
    tag: int | None
    stream: str
    text: str


@dataclass
class TaskDone(Record):
    """A task returned; ``result`` is plain data."""

    run_id: int
    tag: int
    task: str
    result: Any


@dataclass
class TaskFailed(Record):
    """A task ended without a result.

    ``reason``: ``error`` (team code raised), ``cancelled``, ``limit`` (this run broke a limit;
    the message names it) or ``restart`` (another run broke a limit and the child was restarted).
    """

    run_id: int
    tag: int
    task: str
    message: str
    reason: str
    line: int | None = None
    #: For ``error``: the frames of the team's files the error went through, outermost first
    #: (``file:line in function: code``).
    traceback: list[str] = field(default_factory=list)


@dataclass
class Drawing(Record):
    """A robot's new frame of debug drawing, as the child sent it: not to be trusted; the
    robot host and the engine check it (:func:`robo_comp.protocol.drawing.clean_frame`) before it is
    recorded or sent (``robots.teamcode.DebugCanvas``)."""

    run_id: int
    tag: int
    shapes: list


@dataclass
class Loaded(Record):
    """A module passed the contract and is now active (``previous``: version it replaced)."""

    load_id: int
    module: ModuleInfo
    previous: str | None = None


@dataclass
class LoadFailed(Record):
    """A module failed the contract; the previous modules stay active."""

    load_id: int
    file: str
    error: UploadError


@dataclass
class Unloaded(Record):
    """A module was removed."""

    name: str


@dataclass
class SandboxStopped(Record):
    """The child was killed or died. ``respawned``: a fresh child with the good modules follows;
    otherwise ``cooldown`` > 0 says in how many seconds one does (0: closed for good)."""

    reason: str
    message: str
    respawned: bool
    cooldown: float = 0.0


@dataclass
class SandboxRestarted(Record):
    """A cool-down ended (by itself or by :meth:`Sandbox.reset`): a fresh child with the good modules."""

    message: str


# --------------------------------------------------------------------------- internal state
@dataclass
class _Run:
    id: int
    kind: str  # "task" | "load"
    tag: Any
    task: str
    deadline: float | None
    limit_text: str
    calls: set[int] = field(default_factory=set)
    cancelled: bool = False
    violation: str | None = None
    file: str = ""
    source: str = ""
    replay: bool = False
    budget: float = 0.0
    held: bool = False
    last_call: float = 0.0  # when its last robot-API call came (time.monotonic())
    #: The key sent with the answer to its last call; its next call names it when it was sent after
    #: that answer was read (a turn of a loop: see Sandbox.call_rate). 0: none to name.
    key: int = 0


#: The shortest time between two calls of a run the limiter takes as measured (a floor against a
#: clock that did not move).
MIN_PERIOD = 1e-6


class Sandbox:
    """One team's sandbox on one robot host (see the module docstring for the loop contract).

    ``tags`` are the robots of ``team`` on this host; team code can only act for them.
    ``handler(tag, name, args)`` answers robot-API calls (plain data or :data:`PENDING`).
    ``builtin_tasks`` are the host's predefined task names (``code`` modules may replace them).
    """

    def __init__(self, team: str, tags: Iterable[int] = (),
                 handler: Callable[[int, str, list], Any] | None = None,
                 limits: Limits | None = None, *, seed: int = 0,
                 builtin_tasks: Iterable[str] = BUILTIN_TASKS, start: bool = True,
                 deterministic: bool = False) -> None:
        self.team = team
        #: Replayable child (league, bench): it refuses to run where this Python cannot be sealed
        #: against memory addresses, and runs without address randomisation as well (see
        #: docs/sandbox.md, "Determinism"); every child is sealed and has its hash seed fixed.
        self.deterministic = deterministic
        self.tags: list[int] = list(tags)
        self.handler = handler
        self.limits = limits or Limits()
        #: The largest message the parent sends (a module's source fits whatever the limits).
        self._send_cap = max(self.limits.message_bytes, contract.MAX_SOURCE_BYTES + 4096)
        self.seed = seed
        self.builtin_tasks = tuple(builtin_tasks)
        self.proc: subprocess.Popen | None = None
        #: Whether the child runs inside the OS layer (bubblewrap; see sandbox/oswall.py).
        self.os_sandbox = False
        self.sock: socket.socket | None = None
        self._rsock: socket.socket | None = None  # the answers' socket (see start)
        self._rout = bytearray()  # answers the child's socket had no room for yet
        self._reader: FrameReader | None = None
        self._outbuf = bytearray()
        self._out: list[Record] = []
        self._backlog: collections.deque[Record] = collections.deque()
        self._runs: dict[int, _Run] = {}
        self._calls: dict[int, int] = {}  # call id -> run id
        self._next_id = 1
        self._held: list[dict] = []
        self._loads: collections.deque[int] = collections.deque()
        self._throttled: collections.deque[tuple] = collections.deque()
        self._tokens = float(self.limits.rpc_burst)
        self._token_time = time.monotonic()
        #: The shortest time seen between a run's call and its next one (see Limits.rpc_loops).
        self.fastest_loop = math.inf
        self._rate = self.limits.rpc_per_second  # call_rate(), kept
        self._keys: list[int] = []  # unguessable keys for the answers, drawn 512 at a time
        #: Robot-API calls the limiter held back (answered later) so far.
        self.paced_calls = 0
        self._good: dict[str, tuple[str, str, ModuleInfo]] = {}  # name -> (file, source, info)
        self._spawn_deadline: float | None = None
        self._respawns: collections.deque[float] = collections.deque()
        self._killed_by_us: str | None = None
        self.ready = False
        self.closed = False
        self.stopped_reason: str | None = None
        #: While resting after too many limit kills: when the child comes back (time.monotonic()).
        self.cooldown_until: float | None = None
        self._cpu_spent = 0.0  # CPU seconds of the children that have ended (see cpu_seconds)
        self._cpu_counted: subprocess.Popen | None = None  # the child whose CPU is in _cpu_spent
        self._cooldowns = 0  # cool-downs so far (each doubles the next), until reset()
        if start:
            self.start()

    # ------------------------------------------------------------------ process
    def start(self) -> None:
        """Spawn the child (returns at once; a :class:`Ready` record follows)."""
        parent, child = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        # the answers to robot-API calls go on a socket of their own, read in the child by the
        # worker that waits for them (sandbox/child.py, _Replies)
        rparent, rchild = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        # the whole environment is ours (so -E is not needed, and PYTHONHASHSEED is read): hash()
        # of str/bytes and the order of their sets follow the seed, not per-process entropy
        env = {"MALLOC_ARENA_MAX": "1", "PYTHONDONTWRITEBYTECODE": "1",
               "PYTHONHASHSEED": str(1 + self.seed % 4_294_967_295),
               "PATH": os.environ.get("PATH", "/usr/bin:/bin")}
        debug = os.environ.get("ROBO_COMP_SANDBOX_DEBUG") == "1"
        pkg_root = oswall.package_root()
        filter_fd = None
        try:
            wall = oswall.wall(pkg_root)  # the OS layer (bubblewrap, seccomp), or a clear refusal
            cmd = [sys.executable, "-s", "-P", "-B", "-c",  # -I without -E: isolated, but the env above is read
                   f"import sys; sys.path.insert(0, {pkg_root!r}); "
                   # no address reaches team code: sealed before the modules the child needs are imported
                   "from robo_comp.sandbox.determinism import seal_child; seal_child(); "
                   "from robo_comp.sandbox.child import main; main()",
                   "--fd", str(child.fileno()), "--replies", str(rchild.fileno()),
                   "--limits", msgpack.packb(dict(
                       self.limits.wire(self.seed), replayable=self.deterministic,
                       aslr_off=self.deterministic and not keep_aslr(),
                       seccomp=None if wall is None else wall.child_filter())).hex()]
            self.os_sandbox = wall is not None
            if wall is not None:
                cmd, filter_fd = wall.wrap(cmd)
            self.proc = subprocess.Popen(
                cmd, stdin=subprocess.DEVNULL,
                stdout=None if debug else subprocess.DEVNULL,
                stderr=None if debug else subprocess.DEVNULL,
                pass_fds=(child.fileno(), rchild.fileno()) + (() if filter_fd is None else (filter_fd,)),
                start_new_session=True, close_fds=True, env=env, cwd="/")
        except BaseException:
            parent.close()
            rparent.close()
            raise
        finally:
            child.close()
            rchild.close()
            if filter_fd is not None:
                os.close(filter_fd)
        parent.setblocking(False)
        rparent.setblocking(False)
        rparent.shutdown(socket.SHUT_RD)  # answers only go out
        self.sock = parent
        self._rsock = rparent
        self._rout = bytearray()
        self._reader = FrameReader(self.limits.message_bytes)
        self._outbuf = bytearray()
        self.ready = False
        self._killed_by_us = None
        self._spawn_deadline = time.monotonic() + self.limits.spawn_seconds

    @property
    def pid(self) -> int | None:
        """The child's process id (None when not running); inside the OS layer the Python child's
        own, below bwrap's."""
        if self.proc is None or self.proc.returncode is not None:
            return None
        return oswall.leaf_pid(self.proc.pid) if self.os_sandbox else self.proc.pid

    def cpu_seconds(self) -> float:
        """CPU time (user and system) this sandbox's processes have used, every child it has
        started included: its team's code and the child's own work, not the time the child
        waited or the machine spent on others (read from ``/proc``; 0 where there is none)."""
        live = 0.0 if self._cpu_counted is self.proc else _tree_cpu(self.proc)
        return self._cpu_spent + live

    def _count_cpu(self) -> None:
        """Keep the CPU of the child about to end (or just ended, not yet reaped)."""
        if self.proc is not None and self._cpu_counted is not self.proc:
            self._cpu_spent += _tree_cpu(self.proc)
            self._cpu_counted = self.proc

    def memory_mib(self) -> float:
        """Resident memory of the running child in MiB (the Python child, below bwrap's; 0
        where there is none or no ``/proc``)."""
        pid = self.pid
        if pid is None:
            return 0.0
        try:
            with open(f"/proc/{pid}/statm") as f:
                return int(f.read().split()[1]) * _PAGE / 2**20
        except (OSError, ValueError, IndexError):
            return 0.0

    @property
    def alive(self) -> bool:
        """True while a child process is running."""
        return self.proc is not None and self.proc.poll() is None

    def fileno(self) -> int:
        """The socket to poll for reading (-1 when stopped)."""
        return self.sock.fileno() if self.sock is not None else -1

    def deadline(self) -> float | None:
        """Earliest ``time.monotonic()`` at which :meth:`check_timers` must run (or None)."""
        due = self._spawn_deadline
        for r in self._runs.values():  # (a loop, not a list: this runs once per host loop)
            d = r.deadline
            if d is not None and (due is None or d < due):
                due = d
        more = []
        if self._throttled and self.limits.rpc_per_second:
            more.append(self._token_time + max(0.0, 1.0 - self._tokens) / self._rate)
        if self.cooldown_until is not None:
            more.append(self.cooldown_until)
        if self._rout:  # answers wait for room in their socket: look again soon
            more.append(time.monotonic() + REPLY_RETRY)
        if more:
            return min(more) if due is None else min(due, *more)
        return due

    def wants_write(self) -> bool:
        """True when queued outgoing bytes wait for the socket to become writable."""
        return bool(self._outbuf)

    def close(self) -> None:
        """Kill the child and forget everything (the sandbox cannot be used afterwards)."""
        self.closed = True
        self._kill()
        self._runs.clear()
        self._calls.clear()

    def __enter__(self) -> "Sandbox":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # ------------------------------------------------------------------ sending
    def _send(self, msg: dict) -> None:
        if self.sock is None:
            return
        data = pack(msg)
        if len(data) - 4 > self._send_cap:
            raise ValueError("message too large for the sandbox")
        self._outbuf += data
        self._flush()

    def handle_writable(self) -> list[Record]:
        """Flush queued bytes to the child (call when the socket is writable)."""
        self._flush()
        self._flush_replies()
        return self._take()

    def _flush(self) -> None:
        while self._outbuf and self.sock is not None:
            try:
                n = self.sock.send(self._outbuf)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                self._outbuf.clear()
                break
            del self._outbuf[:n]
        if len(self._outbuf) > 8 * 1024 * 1024:
            self._stop("protocol", "the sandbox does not read its messages")

    # ------------------------------------------------------------------ uploads
    def begin_load(self, filename: str, source: str | bytes) -> int:
        """Start loading a module as a candidate; returns the load id.

        A :class:`Loaded` or :class:`LoadFailed` record follows. File-name and size problems
        raise :class:`UploadError` at once.
        """
        try:
            contract.check_filename(filename)
            source = contract.check_source(source)
        except contract.ContractError as exc:
            raise contract.upload_error(str(filename)[:80], exc.rule, exc.detail, exc.line) from None
        return self._begin_load(filename, source, replay=False)

    def _begin_load(self, filename: str, source: str, replay: bool) -> int:
        self._require_running()
        rid = self._new_id()
        budget = self.limits.load_seconds
        run = _Run(rid, "load", self.tags[0] if self.tags else None, "<load>", None,
                   f"wall-clock limit ({budget:g} s) exceeded while loading {filename}: its module body "
                   "computes too long; move slow work into a task or init(robot)",
                   file=filename, source=source, replay=replay, budget=budget, held=True)
        self._runs[rid] = run
        self._loads.append(rid)
        self._next_load()
        return rid

    def _next_load(self) -> None:
        """Loads go to the child one at a time (atomic, in order); the clock starts on send."""
        if any(r.kind == "load" and not r.held for r in self._runs.values()):
            return
        while self._loads:
            run = self._runs.get(self._loads.popleft())
            if run is None:
                continue
            run.held = False
            if self.ready:
                run.deadline = time.monotonic() + run.budget
            self._send({"t": "load", "r": run.id, "g": run.tag, "file": run.file,
                        "src": run.source, "builtin": list(self.builtin_tasks)})
            return

    def load(self, filename: str, source: str | bytes, timeout: float = 10.0) -> ModuleInfo:
        """Blocking :meth:`begin_load`: returns the module or raises :class:`UploadError`.

        Other records arriving meanwhile are kept for the next :meth:`poll`.
        """
        rid = self.begin_load(filename, source)
        rec = self._wait(lambda r: isinstance(r, (Loaded, LoadFailed)) and r.load_id == rid, timeout)
        if rec is None:
            raise UploadError(f"{filename}: timeout: no answer from the sandbox", file=filename,
                              rule="timeout")
        if isinstance(rec, LoadFailed):
            raise rec.error
        assert isinstance(rec, Loaded)  # what the wait above waited for
        return rec.module

    def unload(self, name: str) -> bool:
        """Remove module ``name`` (an :class:`Unloaded` record follows); False if unknown."""
        if name not in self._good:
            return False
        del self._good[name]
        self._send({"t": "unload", "name": name})
        return True

    def modules(self) -> list[ModuleInfo]:
        """The active modules (name, version, kind, file, sha256, tasks, replaces)."""
        return [info for (_, _, info) in self._good.values()]

    def advertised_tasks(self) -> dict[str, dict[str, Any]]:
        """Tasks of the active modules as plain data, keyed by task name.

        Each value: ``{"name", "description", "args": [{"name", "type", "description"}],
        "module", "version", "kind", "replaces_builtin"}``.
        """
        out: dict[str, dict[str, Any]] = {}
        for info in self.modules():
            for tname, spec in info.tasks.items():
                out[tname] = {**spec, "module": info.name, "version": info.version,
                              "kind": info.kind, "replaces_builtin": tname in info.replaces}
        return out

    # ------------------------------------------------------------------ tasks
    def add_tag(self, tag: int) -> None:
        """Let this sandbox act for robot ``tag`` too (one of the team's robots)."""
        if tag not in self.tags:
            self.tags.append(tag)

    def remove_tag(self, tag: int) -> None:
        """Stop acting for ``tag``; its further robot-API calls are refused."""
        if tag in self.tags:
            self.tags.remove(tag)

    def start_task(self, tag: int, task: str, args: list | tuple = ()) -> int:
        """Run ``task`` of a loaded module for robot ``tag``; returns the run id.

        Raises :class:`NotYoursError` for a tag not given to this sandbox and
        :class:`BadTaskError` for an unknown task, wrong arguments or too many runs.
        """
        if tag not in self.tags:
            raise NotYoursError(f"robot {tag} is not one of team {self.team}'s robots here")
        tasks = self.advertised_tasks()
        spec = tasks.get(task)
        if spec is None:
            known = ", ".join(sorted(tasks)) or "none"
            raise BadTaskError(f"no uploaded module provides task {task!r}; uploaded tasks: {known}")
        args = contract.check_task_args(spec, list(args))
        if sum(r.kind == "task" for r in self._runs.values()) >= self.limits.max_runs:
            raise BadTaskError(f"too many tasks running in team {self.team}'s sandbox "
                               f"(limit {self.limits.max_runs}); wait for one to finish, or stop a robot")
        self._require_running(UnavailableError)
        rid = self._new_id()
        budget = self.limits.wall_seconds
        run = _Run(rid, "task", tag, task, time.monotonic() + budget if self.ready else None,
                   f"wall-clock limit ({budget:g} s) exceeded: task {task} computed that long without calling "
                   "the robot (an endless loop?); call the robot now and then (each call starts the clock "
                   "again) or compute less at a time", budget=budget)
        self._runs[rid] = run
        msg = {"t": "run", "r": rid, "g": tag, "task": task, "module": spec["module"], "a": args}
        if self._replaying():
            run.deadline = None  # held until the respawned child has its modules back
            run.held = True
            self._held.append(msg)
        else:
            self._send(msg)
        return rid

    def _replaying(self) -> bool:
        return any(r.replay for r in self._runs.values() if r.kind == "load")

    def _release_held(self) -> None:
        if self._held and not self._replaying():
            held, self._held = self._held, []
            now = time.monotonic()
            for msg in held:
                run = self._runs.get(msg["r"])
                if run is not None:
                    run.held = False
                    if self.ready:
                        run.deadline = now + run.budget
                    self._send(msg)

    def run_task(self, tag: int, task: str, args: list | tuple = (),
                 timeout: float = 30.0) -> TaskDone | TaskFailed | None:
        """Blocking :meth:`start_task`: the run's final record (None on timeout)."""
        rid = self.start_task(tag, task, args)
        rec = self._wait(lambda r: isinstance(r, (TaskDone, TaskFailed)) and r.run_id == rid, timeout)
        assert rec is None or isinstance(rec, (TaskDone, TaskFailed))  # what the wait above waited for
        return rec

    def cancel(self, run_id: int) -> bool:
        """Interrupt/stop a run: its pending robot-API calls fail with ``TaskCancelled`` in team
        code, a computing run gets ``TaskCancelled`` raised at once; if it has not ended after
        ``cancel_grace`` seconds the child is killed. False if the run is unknown."""
        run = self._runs.get(run_id)
        if run is None:
            return False
        if not run.cancelled:
            run.cancelled = True
            run.limit_text = (f"task {run.task} did not stop within {self.limits.cancel_grace:g} s of "
                              "being cancelled (wall-clock limit); let TaskCancelled end your task (do not "
                              "catch it, or raise it again)")
            for call_id in list(run.calls):
                self._answer(call_id, ok=False, error="task cancelled", cancelled=True)
            self._send({"t": "cancel", "r": run_id})
            run.deadline = time.monotonic() + self.limits.cancel_grace
        return True

    def running(self) -> dict[int, tuple[int, str]]:
        """Active task runs: ``{run_id: (tag, task)}``."""
        return {r.id: (r.tag, r.task) for r in self._runs.values() if r.kind == "task"}

    # ------------------------------------------------------------------ rpc answers
    def resolve(self, call_id: int, value: Any) -> None:
        """Answer a pending robot-API call with plain ``value``."""
        self._answer(call_id, ok=True, value=value)

    def reject(self, call_id: int, message: str) -> None:
        """Fail a pending robot-API call; team code gets ``RobotError(message)``."""
        self._answer(call_id, ok=False, error=message)

    def _answer(self, call_id: int, ok: bool, value: Any = None, error: str = "",
                cancelled: bool = False) -> None:
        rid = self._calls.pop(call_id, None)
        if rid is None:
            return
        run = self._runs.get(rid)
        msg: dict[str, Any] = {"t": "reply", "c": call_id, "ok": ok}
        if run is not None:
            run.calls.discard(call_id)
            if run.kind == "task" and not run.cancelled and not run.calls:
                run.deadline = time.monotonic() + self.limits.wall_seconds
            if not self._keys:
                self._keys = array.array("Q", os.urandom(4096)).tolist()
            run.key = msg["k"] = self._keys.pop() or 1
        if ok:
            msg["v"] = value
        else:
            msg["e"] = str(error)[:1000]
            if cancelled:
                msg["x"] = True
        try:
            data = pack(msg)
            if len(data) - 4 > self._send_cap:
                raise ValueError("message too large for the sandbox")
        except (TypeError, ValueError, OverflowError) as exc:
            data = pack({"t": "reply", "c": call_id, "ok": False,
                         "e": f"the host's answer is not plain data or too large ({exc})"})
        if self._rsock is None:
            return
        if not self._rout:  # most often: straight out, nothing queued
            try:
                n = self._rsock.send(data)
            except (BlockingIOError, InterruptedError):
                n = 0
            except OSError:
                return
            if n == len(data):
                return
            data = data[n:]
        self._rout += data
        self._flush_replies()

    def _flush_replies(self) -> None:
        """Send the answers waiting for room in their socket (never blocks)."""
        while self._rout and self._rsock is not None:
            try:
                n = self._rsock.send(self._rout)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                self._rout.clear()
                break
            del self._rout[:n]
        if len(self._rout) > 8 * 1024 * 1024:
            self._stop("protocol", "the sandbox does not read the answers to its calls")

    # ------------------------------------------------------------------ the loop side
    def poll(self, timeout: float = 0.0) -> list[Record]:
        """Wait up to ``timeout`` for input, then do all pending work; returns records."""
        if self._backlog:
            out: list[Record] = list(self._backlog)
            self._backlog.clear()
            return out + self.check_timers()
        if self.sock is not None:
            d = self.deadline()
            if d is not None:
                timeout = max(0.0, min(timeout, d - time.monotonic()))
            wl = [self.sock] if self._outbuf else []
            try:
                r, w, _ = select.select([self.sock], wl, [], timeout)
            except (OSError, ValueError):
                r, w = [], []
            out = []
            if w:
                out += self.handle_writable()
            if r:
                out += self.handle_readable()
            return out + self.check_timers()
        if timeout:
            time.sleep(timeout)
        return self.check_timers()

    def handle_readable(self) -> list[Record]:
        """Read what the child sent and process it; returns records."""
        if self.sock is None or self._reader is None:
            return self._take()
        while self.sock is not None:
            try:
                data = self.sock.recv(RECV_BYTES)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                data = b""
            if not data:
                self._child_gone()
                break
            try:
                msgs = self._reader.feed(data)
            except FrameError as exc:
                self._stop("message", str(exc))
                break
            for msg in msgs:
                try:
                    self._dispatch(msg)
                except (KeyError, TypeError, ValueError, AttributeError):
                    self._stop("protocol", f"protocol violation in a {str(msg.get('t'))[:20]!r} "
                                           "message")
                    break
            if len(data) < RECV_BYTES:
                break
        return self._take()

    def check_timers(self, now: float | None = None) -> list[Record]:
        """Enforce wall-clock limits (kill + respawn); returns records."""
        now = time.monotonic() if now is None else now
        if self._rout:
            self._flush_replies()
        if self.cooldown_until is not None:
            if now >= self.cooldown_until:
                self._restart("the sandbox's cool-down is over: it runs again with your loaded modules")
            return self._take()
        if self._throttled:
            self._release_throttled()
        if self._spawn_deadline is not None and now >= self._spawn_deadline:
            self._stop("spawn", f"the sandbox did not start within {self.limits.spawn_seconds:g} s")
            return self._take()
        run = None
        for r in self._runs.values():  # the run late the longest (a loop: this runs once per host loop)
            d = r.deadline
            if d is not None and now >= d and (run is None or d < (run.deadline or 0.0)):
                run = r
        if run is not None:
            self._stop("wall", run.violation or run.limit_text, culprit=run.id)
        return self._take()

    def _take(self) -> list[Record]:
        out, self._out = self._out, []
        return out

    # ------------------------------------------------------------------ dispatch
    def _dispatch(self, msg: dict) -> None:
        t = msg["t"]
        if t == "call":
            self._on_call(msg)
        elif t == "log":
            text = msg["text"]
            if type(text) is not str:
                raise TypeError
            run = self._runs.get(msg.get("run", -1))
            self._out.append(LogLine(run.id if run else None, run.tag if run else None,
                                     str(msg.get("stream", "print"))[:10], text))
        elif t in ("done", "failed"):
            run = self._runs.pop(msg["r"], None)
            if run is None:
                return
            self._forget_calls(run)
            if t == "done":
                self._out.append(TaskDone(run.id, run.tag, run.task, msg.get("v")))
            else:
                why = str(msg.get("why", "error"))
                if why not in ("error", "cancelled", "limit"):
                    why = "error"
                if run.cancelled and why == "error":
                    why = "cancelled"
                text = str(msg.get("m", ""))[:2000]
                tb = msg.get("tb")
                trace = [str(x)[:300] for x in tb[:20]] if type(tb) is list and why == "error" else []
                self._out.append(TaskFailed(run.id, run.tag, run.task, text, why,
                                            msg.get("line") if type(msg.get("line")) is int else None, trace))
        elif t == "draw":
            run = self._runs.get(msg.get("r", -1))
            if run is not None and run.kind == "task":
                shapes = msg.get("s")  # checked where it is recorded: teamcode.DebugCanvas (clean_frame)
                self._out.append(Drawing(run.id, run.tag, shapes if type(shapes) is list else []))
        elif t == "loaded":
            run = self._runs.pop(msg["r"], None)
            if run is None:
                return
            self._forget_calls(run)
            tasks = msg["tasks"]
            if type(tasks) is not dict:
                raise TypeError
            info = ModuleInfo(name=str(msg["name"]), version=str(msg["version"]),
                              kind=str(msg["kind"]), file=run.file,
                              sha256=contract.source_hash(run.source), tasks=tasks,
                              description=str(msg.get("description", "")),
                              replaces=[t for t in tasks if t in self.builtin_tasks])
            prev = self._good.get(info.name)
            if run.replay and prev is None:  # unloaded while it was being replayed
                self._send({"t": "unload", "name": info.name})
                self._next_load()
                self._release_held()
                return
            self._good[info.name] = (run.file, run.source, info)
            self._out.append(Loaded(run.id, info, prev[2].version if prev else None))
            self._next_load()
            self._release_held()
        elif t == "load_failed":
            run = self._runs.pop(msg["r"], None)
            if run is None:
                return
            self._forget_calls(run)
            line = msg.get("line") if type(msg.get("line")) is int else None
            err = contract.upload_error(run.file, str(msg.get("rule", "contract"))[:20],
                                        str(msg.get("m", ""))[:1000], line)
            if run.replay:
                self._good = {k: v for k, v in self._good.items() if v[0] != run.file}
            self._out.append(LoadFailed(run.id, run.file, err))
            self._next_load()
            self._release_held()
        elif t == "phase":
            run = self._runs.get(msg["r"])
            if run is not None and msg.get("phase") == "init":
                run.deadline = time.monotonic() + self.limits.init_seconds
                run.limit_text = (f"{run.file}: init: init(robot) did not finish within "
                                  f"{self.limits.init_seconds:g} s (wall-clock limit); keep init short "
                                  "(set up your state) and do long work in a task")
        elif t == "violation":
            run = self._runs.get(msg["r"])
            if run is not None and run.violation is None:
                run.violation = str(msg.get("message", "limit exceeded"))[:300]
        elif t == "unloaded":
            self._out.append(Unloaded(str(msg.get("name"))))
        elif t == "ready":
            self.ready = True
            self._spawn_deadline = None
            now = time.monotonic()
            for run in self._runs.values():  # the clocks start when the child can work
                if run.deadline is None and not run.held and not run.calls:
                    run.deadline = now + run.budget
            self._out.append(Ready(int(msg["pid"])))
        else:
            raise ValueError(t)

    def _on_call(self, msg: dict) -> None:
        call_id, rid, tag, name, args = msg["c"], msg["r"], msg["g"], msg["n"], msg["a"]
        if type(call_id) is not int or type(name) is not str or type(args) is not list:
            raise TypeError
        run = self._runs.get(rid)
        if run is None:
            raise KeyError(rid)
        now = time.monotonic()
        if run.key and msg.get("k") == run.key:
            # the call names the key of its run's last answer: it was sent after that answer was
            # read, so the time since that call is one turn of a loop. Calls sent without waiting
            # cannot know the key (drawn from os.urandom), whichever read of the socket they come
            # in: they are held to the rate and do not raise it.
            period = max(MIN_PERIOD, now - run.last_call)
            if period < self.fastest_loop:
                self.fastest_loop = period
                self._rate = self.call_rate()
        run.key = 0
        run.last_call = now
        run.calls.add(call_id)
        self._calls[call_id] = rid
        if run.kind == "task":
            run.deadline = None  # waiting for the host: no wall-clock
        if tag not in self.tags:
            self._answer(call_id, ok=False,
                         error=f"robot {tag} is not one of team {self.team}'s robots here")
            return
        if run.cancelled:
            self._answer(call_id, ok=False, error="task cancelled", cancelled=True)
            return
        if self._throttled or not self._take_token(now):
            self._throttled.append((call_id, rid, tag, name, args))  # answered when due
            self.paced_calls += 1
            return
        self._deliver(call_id, rid, tag, name, args)

    def call_rate(self) -> float:
        """The limiter's rate now, calls per second (0: no limiter): ``rpc_per_second``, or
        ``rpc_loops`` times the calls per second of the fastest loop measured if that is more."""
        rate = self.limits.rpc_per_second
        if rate and self.fastest_loop < math.inf:
            rate = max(rate, self.limits.rpc_loops / self.fastest_loop)
        return rate

    def _take_token(self, now: float | None = None) -> bool:
        rate = self._rate
        if not rate:
            return True
        if now is None:
            now = time.monotonic()
        self._tokens = min(float(self.limits.rpc_burst),
                           self._tokens + (now - self._token_time) * rate)
        self._token_time = now
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        return False

    def _release_throttled(self) -> None:
        while self._throttled and self._take_token():
            call_id, rid, tag, name, args = self._throttled.popleft()
            if call_id in self._calls and rid in self._runs:
                self._deliver(call_id, rid, tag, name, args)

    def _deliver(self, call_id: int, rid: int, tag: int, name: str, args: list) -> None:
        """Hand one robot-API call to the handler (or out as an :class:`RpcCall`)."""
        if self.handler is None:
            self._out.append(RpcCall(call_id, rid, tag, name, args))
            return
        try:
            value = self.handler(tag, name, args)
        except Exception as exc:  # the host refused (bad args, unavailable, ...)
            self._answer(call_id, ok=False, error=str(getattr(exc, "message", exc)))
            return
        if value is not PENDING:
            self._answer(call_id, ok=True, value=value)

    def _forget_calls(self, run: _Run) -> None:
        for c in run.calls:
            self._calls.pop(c, None)

    # ------------------------------------------------------------------ death and respawn
    def _child_gone(self) -> None:
        rc = None
        self._count_cpu()  # before it is reaped: then /proc forgets it
        if self.proc is not None:
            try:
                rc = self.proc.wait(timeout=2.0)
            except subprocess.TimeoutExpired:
                self._kill()
                rc = self.proc.returncode
        reason, text = self._classify(oswall.exit_code(rc, self.os_sandbox))
        self._stop(reason, text, already_dead=True)

    def _classify(self, rc: int | None) -> tuple[str, str]:
        L = self.limits
        if rc == -signal.SIGXCPU:
            return "cpu", (f"CPU time limit ({L.cpu_seconds} s) exceeded: your code computed too long "
                           "without calling the robot; split the work into steps with robot calls between them")
        if rc == EXIT_MEMORY:
            return "memory", (f"memory limit ({L.memory_mib} MiB) exceeded: your code kept too much data; "
                              "keep fewer or smaller lists and dicts (e.g. one set of visited cells)")
        if rc == -signal.SIGXFSZ:
            return "file", "file size limit exceeded (team code may not write files)"
        if rc in (-signal.SIGSEGV, -signal.SIGABRT, -signal.SIGBUS):
            return "memory", (f"memory limit ({L.memory_mib} MiB) exceeded (the sandbox crashed "
                              f"with {signal.Signals(-rc).name})")
        if rc == -signal.SIGKILL:
            return "killed", "the sandbox was killed (CPU or memory limit of the system)"
        if rc == EXIT_PROTOCOL:
            return "protocol", "the sandbox received a malformed message"
        if rc == EXIT_INTERNAL:
            return "crash", "the sandbox failed internally"
        return "exit", f"the sandbox exited (code {rc})"

    def _near_memory_limit(self) -> bool:
        """True if the child's address space is within 30% of its limit (Linux /proc)."""
        if self.proc is None:
            return False
        try:
            with open(f"/proc/{self.pid}/status", "rb") as f:
                for line in f:
                    if line.startswith(b"VmPeak:"):
                        kib = int(line.split()[1])
                        return kib * 1024 >= 0.7 * self.limits.memory_mib * 1024 * 1024
        except (OSError, ValueError, IndexError):
            pass
        return False

    def _kill(self) -> None:
        if self.proc is not None and self.proc.returncode is None:
            self._count_cpu()
        if self.proc is not None and self.proc.poll() is None:
            if self.os_sandbox:  # the child first: bwrap's init reaps it and then bwrap ends
                inner = self.pid
                if inner is not None and inner != self.proc.pid:
                    with contextlib.suppress(ProcessLookupError, PermissionError):
                        os.kill(inner, signal.SIGKILL)
                    with contextlib.suppress(subprocess.TimeoutExpired):
                        self.proc.wait(timeout=2.0)
        if self.proc is not None and self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                try:
                    self.proc.kill()
                except ProcessLookupError:
                    pass
            try:
                self.proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:  # pragma: no cover
                pass
        if self.sock is not None:
            try:
                self.sock.close()
            except OSError:
                pass
            self.sock = None
        if self._rsock is not None:
            self._rsock.close()
            self._rsock = None
        self._rout.clear()

    def _stop(self, reason: str, message: str, culprit: int | None = None,
              already_dead: bool = False) -> None:
        """Kill the child, fail its runs, and respawn it with the good modules."""
        if not already_dead and self.proc is not None and self.proc.poll() is not None:
            # it died by itself before we noticed (e.g. SIGXCPU): report that instead
            reason, message = self._classify(oswall.exit_code(self.proc.returncode, self.os_sandbox))
            culprit = None
        elif reason == "wall" and self._near_memory_limit():
            # team code swallowed its MemoryErrors and spun: name the real cause
            reason = "memory"
            message = (f"memory limit ({self.limits.memory_mib} MiB) exceeded: your code kept too much data; "
                       "keep fewer or smaller lists and dicts (e.g. one set of visited cells)")
            for r in self._runs.values():
                if r.id == culprit and r.violation is None:
                    r.violation = message
        self._kill()
        runs = sorted(self._runs.values(), key=lambda r: r.id)
        self._runs.clear()
        self._held = []
        self._loads.clear()
        self._throttled.clear()
        self._calls.clear()
        if culprit is None:
            computing = [r for r in runs if r.deadline is not None and not r.calls]
            if computing:
                culprit = min(computing, key=lambda r: r.deadline or 0.0).id
            elif runs:
                culprit = runs[0].id
        requeue: list[_Run] = []
        for r in runs:
            text = (r.violation or message) if r.id == culprit else \
                f"sandbox restarted: {message}"
            if r.kind == "task":
                why = "limit" if r.id == culprit else "restart"
                self._out.append(TaskFailed(r.id, r.tag, r.task, text, why))
            elif r.id == culprit:
                rule = "init" if "init" in r.limit_text and r.limit_text is text else "limit"
                self._out.append(LoadFailed(r.id, r.file, contract.upload_error(r.file, rule, text)))
                if r.replay:
                    self._good = {k: v for k, v in self._good.items() if v[0] != r.file}
            elif not r.replay:
                requeue.append(r)  # an innocent upload waiting its turn: try it again
        now = time.monotonic()
        while self._respawns and now - self._respawns[0] > self.limits.respawn_window:
            self._respawns.popleft()
        respawn = not self.closed and len(self._respawns) < self.limits.max_respawns
        if not respawn:
            cooldown = 0.0
            if not self.closed:
                cooldown = min(self.limits.max_cooldown, self.limits.cooldown_seconds * 2 ** self._cooldowns)
                self._cooldowns += 1
                self.cooldown_until = now + cooldown
                message = (f"{message}. Your code hit the sandbox's limits {len(self._respawns) + 1} times "
                           f"within {self.limits.respawn_window:g} s, so the sandbox rests for {cooldown:g} s and "
                           "then restarts by itself with your loaded modules (the referee can restart it "
                           "sooner); meanwhile your uploaded tasks do not run. Fix the code that hits the "
                           "limit (the task named above) and upload it again")
            self._out.append(SandboxStopped(reason, message, False, cooldown))
            self.stopped_reason = message
            self._spawn_deadline = None
            for r in requeue:
                self._out.append(LoadFailed(r.id, r.file, contract.upload_error(
                    r.file, "limit", f"sandbox stopped: {message}")))
            return
        self._out.append(SandboxStopped(reason, message, True))
        self._respawns.append(now)
        self._respawn(requeue)

    def reset(self) -> bool:
        """The referee's restart: end a cool-down now and forget the kills counted so far.
        Returns True when the sandbox was resting (it restarts with the good modules)."""
        self._cooldowns = 0
        self._respawns.clear()
        if self.cooldown_until is None or self.closed:
            return False
        self._restart("the referee restarted the sandbox: it runs again with your loaded modules")
        return True

    def _restart(self, why: str) -> None:
        """End a cool-down: a fresh child with the good modules."""
        self.cooldown_until = None
        self.stopped_reason = None
        self._respawns.clear()
        self._out.append(SandboxRestarted(why))
        self._respawn([])

    def _respawn(self, requeue: list[_Run]) -> None:
        """Start a fresh child, load the good modules again, then the innocent uploads that waited."""
        self.start()
        for file, source, _info in list(self._good.values()):
            self._begin_load(file, source, replay=True)
        for r in requeue:
            r.held, r.deadline, r.calls = True, None, set()
            self._runs[r.id] = r
            self._loads.append(r.id)
        self._next_load()

    # ------------------------------------------------------------------ helpers
    def _new_id(self) -> int:
        rid = self._next_id
        self._next_id += 1
        return rid

    def _require_running(self, error: type = UploadError) -> None:
        if self.closed:
            raise error(f"team {self.team}'s sandbox is closed")
        if self.sock is None:
            if self.cooldown_until is not None:
                left = max(0.0, self.cooldown_until - time.monotonic())
                raise error(f"team {self.team}'s sandbox is resting after too many limit kills: it restarts by "
                            f"itself in {math.ceil(left)} s with your loaded modules (sooner if the referee restarts it); "
                            "try again then")
            raise error(f"team {self.team}'s sandbox is stopped: {self.stopped_reason}")

    def _wait(self, pred: Callable[[Record], bool], timeout: float) -> Record | None:
        end = time.monotonic() + timeout
        kept: list[Record] = []
        found = None
        while found is None:
            left = end - time.monotonic()
            if left <= 0:
                break
            for rec in self.poll(min(left, 0.5)):
                if found is None and pred(rec):
                    found = rec
                else:
                    kept.append(rec)
        self._backlog.extend(kept)
        return found


_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096
_TICKS = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def _tree_cpu(proc: subprocess.Popen | None) -> float:
    """CPU seconds of ``proc`` and its chain of only children (bwrap → its init → the child):
    each one's own user and system time plus that of the children it has reaped (a child that
    ended inside bwrap counts with the one that waited for it). 0 where /proc is not there."""
    if proc is None or proc.returncode is not None:
        return 0.0
    total = 0
    for pid in oswall.chain(proc.pid):
        try:
            with open(f"/proc/{pid}/stat", "rb") as f:
                fields = f.read().rsplit(b")", 1)[1].split()
        except (OSError, IndexError):
            continue
        total += sum(int(x) for x in fields[11:15])  # utime stime cutime cstime
    return total / _TICKS


def poll_many(sandboxes: Iterable[Sandbox], timeout: float = 0.0) -> list[tuple[Sandbox, Record]]:
    """One iteration of a host loop over several sandboxes: wait up to ``timeout`` (bounded by
    their deadlines) for any of them, then process all; returns ``(sandbox, record)`` pairs."""
    boxes = list(sandboxes)
    out: list[tuple[Sandbox, Record]] = []
    for sb in boxes:
        while sb._backlog:
            out.append((sb, sb._backlog.popleft()))
    if out:
        timeout = 0.0
    now = time.monotonic()
    for sb in boxes:
        d = sb.deadline()
        if d is not None:
            timeout = min(timeout, max(0.0, d - now))
    rl = [sb for sb in boxes if sb.sock is not None]
    wl = [sb for sb in rl if sb.wants_write()]
    if rl:
        try:
            r, w, _ = select.select(rl, wl, [], timeout)
        except (OSError, ValueError):
            r, w = [], []
    else:
        r, w = [], []
        if timeout:
            time.sleep(timeout)
    for sb in w:
        out.extend((sb, rec) for rec in sb.handle_writable())
    for sb in r:
        out.extend((sb, rec) for rec in sb.handle_readable())
    for sb in boxes:
        out.extend((sb, rec) for rec in sb.check_timers())
    return out
