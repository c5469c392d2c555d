"""Where a robot host plans its robots' paths: a process of its own, at the lowest priority.

A host of hundreds of robots plans a path whenever a task yields ``Plan(goal)`` (and again
whenever a robot waits for a teammate). The search itself is compiled and releases the GIL, but
the glue around it holds it; a planner *thread* at a low priority that the OS preempts while it
holds the GIL keeps the host's loop waiting for as long as the thread waits for a core (12 ms on
average, measured with 8 busy hosts on 2 cores): a stop waited behind it. In a process of its own
the planner shares no GIL with the loop, and at ``nice`` 19 it takes only the CPU the loops leave.

:class:`HostPlanner` answers each plan with a future, as the thread did. The planner process
(``python -m robo_comp.robots.planning``, started by the host's loop, never a fork of its threads)
reads requests on its stdin and writes answers on its stdout, each a length-prefixed pickle; the
map goes over only when it changed since the last request (a robot found an obstacle). A thread of
the host writes the requests, so the loop never waits for the pipe. The process ends when the host
closes its stdin or dies (Linux's parent-death signal, else the closed pipe).
If it dies, the plans it held are planned again in the host's own planner thread and the next plan
starts a new process. The host waits for its first process to load its kernels before its robots
register (:meth:`HostPlanner.wait_ready`); a process started later (after one died) gets no plan
until it has, they are made in the thread meanwhile. Where no process can be started, the thread
plans everything.

A process pays off where a host plans a lot: a host of :data:`PROCESS_FROM` robots or more starts
one (``robo-comp robots --planner auto``, the default); a host of a few robots plans in its thread
and spends no process (``--planner process`` or ``thread`` choose).
"""
from __future__ import annotations

import logging
import os
import pickle
import queue
import signal
import struct
import subprocess
import sys
import threading
from concurrent.futures import Future, InvalidStateError, ThreadPoolExecutor
from typing import IO, Any

from robo_comp.errors import FieldError

log = logging.getLogger("robo_comp.robots")

#: The planner process's scheduling priority (``nice``): the lowest; it plans with what the hosts'
#: loops leave of the machine.
PROCESS_NICE = 19
#: How much lower the host's planner thread's priority is than its loop's (Linux schedules threads
#: on their own). The thread writes videos, and plans only when the process cannot.
THREAD_NICE = 10
#: Robots from which a host plans in a process of its own (``--planner auto``).
PROCESS_FROM = 32
#: Where a host may plan (``robo-comp robots --planner``): a process from :data:`PROCESS_FROM`
#: robots, always a process, always a thread.
PLANNER_CHOICES = ("auto", "process", "thread")
#: The job number of the planner process's first answer: it has loaded its kernels.
READY = 0

Path_ = list[tuple[int, int]] | None
_LEN = struct.Struct("<I")


class PlannerGone(RuntimeError):
    """The planner process ended with plans still to answer."""


def _lower_thread_priority() -> None:
    """Run in the planner thread: lower this thread's priority (where the OS has per-thread nice)."""
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), THREAD_NICE)
    except (AttributeError, OSError):  # not Linux, or not allowed: plans then compete as equals
        pass


def _write(out: IO[bytes], obj: Any) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    out.write(_LEN.pack(len(data)) + data)
    out.flush()


def _read(inp: IO[bytes]) -> Any:
    """The next pickle on ``inp``; None at its end."""
    head = inp.read(_LEN.size)
    if len(head) < _LEN.size:
        return None
    size = _LEN.unpack(head)[0]
    data = inp.read(size)
    if len(data) < size:
        return None
    return pickle.loads(data)


def _die_with_parent(parent: int) -> None:
    """Linux: be killed when the host dies (a host killed with SIGKILL leaves no planner behind)."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:  # the host died before the signal was asked for
        os._exit(0)


def _plan(walls: Any, start: tuple[int, int], goal: tuple[int, int], occupied: set[tuple[int, int]]) -> Path_:
    """:func:`~robo_comp.robots.runtime.plan_around`, imported when first used: the command line
    reads :data:`PLANNER_CHOICES` from this module without loading the planner."""
    from robo_comp.robots.runtime import plan_around

    return plan_around(walls, start, goal, occupied)


def serve(parent: int) -> None:
    """The planner process: take ``("walls", array)`` (the map from now on) and answer
    ``(job, start, goal, occupied)`` with ``(job, ok, path or error)`` until stdin ends. Requests
    come from one trusted host."""
    _die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the host's to handle
    try:
        os.setpriority(os.PRIO_PROCESS, 0, PROCESS_NICE)
    except (AttributeError, OSError):
        pass
    import robo_comp.robots.runtime  # noqa: F401  (loaded before it says it is ready, not at the first plan)
    from robo_comp.world.planner import warm_up

    warm_up(jumps=False)
    inp, out = sys.stdin.buffer, sys.stdout.buffer
    sys.stdout = sys.stderr  # nothing but answers on the answer pipe
    _write(out, (READY, True, None))
    walls: Any = None
    while True:
        req = _read(inp)
        if req is None:
            return
        if req[0] == "walls":
            walls = req[1]
            continue
        job, start, goal, occupied = req
        try:
            answer: tuple[Any, ...] = (job, True, _plan(walls, start, goal, occupied))
        except Exception as e:  # a planner bug fails that plan (and its task), not the host
            answer = (job, False, repr(e))
        _write(out, answer)


class HostPlanner:
    """A host's planner: :meth:`plan` returns a future of a path (see the module docstring);
    :meth:`run` runs other slow work (a video's encoding) in the host's low-priority thread."""

    @classmethod
    def for_host(cls, choice: str, robots: int) -> HostPlanner:
        """The planner of a host of ``robots`` robots that chose ``choice`` (one of
        :data:`PLANNER_CHOICES`; :class:`~robo_comp.errors.FieldError` for another)."""
        if choice not in PLANNER_CHOICES:
            raise FieldError(f"planner must be one of {', '.join(PLANNER_CHOICES)}, not {choice!r}")
        return cls(use_process=choice == "process" or (choice == "auto" and robots >= PROCESS_FROM))

    def __init__(self, use_process: bool = True) -> None:
        self.thread = ThreadPoolExecutor(max_workers=1, thread_name_prefix="planner",
                                         initializer=_lower_thread_priority)
        self.use_process = use_process
        self._proc: subprocess.Popen[bytes] | None = None
        self._ready: subprocess.Popen[bytes] | None = None  # the process once it has said it is ready
        self._said_ready = threading.Event()
        self._lock = threading.Lock()
        self._pending: dict[int, tuple[Future[Path_], tuple[Any, ...]]] = {}
        self._jobs = 0
        # Requests for the writer thread: (process, job, args); None ends it.
        self._out: queue.SimpleQueue[tuple[subprocess.Popen[bytes], int, tuple[Any, ...]] | None] = queue.SimpleQueue()
        self._writer: threading.Thread | None = None
        #: Times the planner process was started (1 once it is up; more after it died).
        self.starts = 0

    def start(self) -> None:
        """Start the planner process now (it loads its kernels before the first plan comes)."""
        self._process()

    def _process(self) -> subprocess.Popen[bytes] | None:
        if self._proc is not None and self._proc.poll() is None:
            return self._proc
        if not self.use_process:
            return None
        try:
            proc = subprocess.Popen([sys.executable, "-m", "robo_comp.robots.planning", str(os.getpid())],
                                    stdin=subprocess.PIPE, stdout=subprocess.PIPE, close_fds=True)
        except OSError as e:
            log.warning("planning in a thread: cannot start a planner process (%s)", e)
            self.use_process = False
            return None
        self._proc = proc
        self.starts += 1
        threading.Thread(target=self._answers, args=(proc,), name="planner-answers", daemon=True).start()
        if self._writer is None:
            self._writer = threading.Thread(target=self._requests, name="planner-requests", daemon=True)
            self._writer.start()
        return proc

    def _requests(self) -> None:
        """Thread: write each request to its process, the map first when it changed."""
        sent: dict[int, Any] = {}  # process pid -> the map it has
        while True:
            item = self._out.get()
            if item is None:
                return
            proc, job, args = item
            walls, rest = args[0], args[1:]
            try:
                assert proc.stdin is not None
                have = sent.get(proc.pid)
                if have is None or have.shape != walls.shape or not (have == walls).all():
                    have = walls.copy()
                    _write(proc.stdin, ("walls", have))
                    sent = {proc.pid: have}
                _write(proc.stdin, (job, *rest))
            except (OSError, ValueError):  # the process is gone: its answers thread plans it here
                with self._lock:
                    pending = self._pending.pop(job, None)
                if pending is not None:
                    self._in_thread(*pending)

    def _answers(self, proc: subprocess.Popen[bytes]) -> None:
        """Thread: hand each answer of ``proc`` to its future; when it ends, plan what it held in
        the host's thread."""
        assert proc.stdout is not None
        while True:
            try:
                ans = _read(proc.stdout)
            except Exception:  # a torn answer: the process is gone or broken
                ans = None
            if ans is None:
                break
            job, ok, value = ans
            if job == READY:
                self._ready = proc
                self._said_ready.set()
                continue
            with self._lock:
                item = self._pending.pop(job, None)
            if item is None:
                continue
            if ok:
                _settle(item[0], value, None)
            else:
                _settle(item[0], None, PlannerGone(f"planner: {value}"))
        proc.wait()
        if self._ready is not proc and self.use_process:  # it never came up: do not start one a plan
            log.warning("the planner process ended before it was ready (code %s); planning in the host's thread",
                        proc.returncode)
            self.use_process = False
        with self._lock:
            if self._proc is proc:
                self._proc = None
            left = list(self._pending.values())
            self._pending.clear()
        if left:
            log.warning("the planner process ended (code %s); %d plans made in the host's thread",
                        proc.returncode, len(left))
        for outer, args in left:
            self._in_thread(outer, args)

    def _in_thread(self, outer: Future[Path_], args: tuple[Any, ...]) -> None:
        try:
            redo = self.thread.submit(_plan, *args)
        except RuntimeError as e:  # the host is shutting down
            _settle(outer, None, e)
            return
        redo.add_done_callback(lambda g: _settle(outer, *_outcome(g)))

    def plan(self, walls: Any, start: tuple[int, int], goal: tuple[int, int],
             occupied: set[tuple[int, int]]) -> Future[Path_]:
        """A future of :func:`~robo_comp.robots.runtime.plan_around`'s answer."""
        args = (walls, start, goal, occupied)
        proc = self._process()
        if proc is None or self._ready is not proc:  # none, or still loading its kernels
            return self.thread.submit(_plan, *args)
        outer: Future[Path_] = Future()
        with self._lock:
            self._jobs += 1
            job = self._jobs
            self._pending[job] = (outer, args)
        self._out.put((proc, job, args))
        return outer

    def run(self, fn: Any, *args: Any) -> Future[Any]:
        """Run ``fn(*args)`` in the host's low-priority thread."""
        return self.thread.submit(fn, *args)

    def pid(self) -> int | None:
        """The planner process's pid, while it runs (for tests and benches)."""
        proc = self._proc
        return proc.pid if proc is not None and proc.poll() is None else None

    def wait_ready(self, timeout: float) -> bool:
        """Wait up to ``timeout`` seconds for the planner process (if any) to load its kernels;
        whether plans go to it now."""
        if self._process() is None:
            return False
        self._said_ready.wait(timeout)
        return self.ready()

    def ready(self) -> bool:
        """Whether plans go to the planner process now (it runs and has loaded its kernels)."""
        proc = self._proc
        return proc is not None and self._ready is proc and proc.poll() is None

    def shutdown(self) -> None:
        """Stop planning: the process ends, plans not answered are cancelled."""
        self.use_process = False
        proc, self._proc = self._proc, None
        with self._lock:
            left = list(self._pending.values())
            self._pending.clear()
        for outer, _ in left:
            outer.cancel()
        self._out.put(None)
        if proc is not None:
            try:
                assert proc.stdin is not None
                proc.stdin.close()
            except OSError:
                pass
            try:
                proc.wait(timeout=2.0)
            except subprocess.TimeoutExpired:
                proc.kill()
        self.thread.shutdown(wait=False, cancel_futures=True)


def _outcome(f: Future[Any]) -> tuple[Any, BaseException | None]:
    if f.cancelled():
        return None, PlannerGone("cancelled")
    exc = f.exception()
    return (None, exc) if exc is not None else (f.result(), None)


def _settle(outer: Future[Any], value: Any, exc: BaseException | None) -> None:
    """Give ``outer`` its outcome (unless it was cancelled meanwhile: the task dropped its plan)."""
    try:
        if exc is not None:
            outer.set_exception(exc)
        else:
            outer.set_result(value)
    except InvalidStateError:
        pass


if __name__ == "__main__":
    serve(int(sys.argv[1]) if len(sys.argv) > 1 else os.getppid())


__all__ = ["HostPlanner", "PLANNER_CHOICES", "PROCESS_FROM", "PROCESS_NICE", "PlannerGone", "READY", "THREAD_NICE", "serve"]
