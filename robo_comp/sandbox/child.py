"""The sandbox child process: runs one team's modules for one robot host, under limits.

Started by :class:`robo_comp.sandbox.parent.Sandbox` as::

    python -s -P -B -c "...; seal_child(); from robo_comp.sandbox.child import main; main()" \
        --fd N --replies M --limits <msgpack hex>

(``-I`` but for ``-E``: the parent gives the whole environment, and ``PYTHONHASHSEED`` in it
fixes ``hash()`` per match; :func:`robo_comp.sandbox.determinism.seal_child` first takes
memory addresses out of every default repr and hash; a replayable child also starts itself
again once with address randomisation off, see :func:`_without_aslr`.)

Order of start-up (everything that needs files or new threads happens *before* the limits):
import all we need → die-with-parent → drop root to ``nobody`` (if root) → start the worker
threads → inside the OS layer, the seccomp filter that refuses new programs → rlimits (CPU,
address space, no new processes, no new files, no file writes, no core) → send ``ready``. Then the
main thread only reads messages from the parent and dispatches them; team code (module bodies,
``init``, tasks) runs in the worker threads, one run each. The answers to robot-API calls come
on a second socket (``--replies``), which the worker waiting for an answer reads itself
(:class:`_Replies`): no thread hands a call's answer to another.

Wire format (both directions, both sockets): 4-byte big-endian length + a msgpack map with key ``t``.
This module also holds the framing helpers the parent uses.
"""
from __future__ import annotations

import argparse
import ast
import math
import os
import queue
import resource
import select
import signal
import socket
import struct
import sys
import threading
import time
import types
from typing import Any, Callable, TypeGuard

import msgpack

from robo_comp.protocol import drawing as _drawing
from robo_comp.sandbox import api as _api, explain, sysfilter

HEADER = struct.Struct(">I")
EXIT_MEMORY = 75
EXIT_PROTOCOL = 76
#: Robot calls that move the robot: a frame of debug drawing is sent just before each.
_MOVEMENT = frozenset({"move", "turn", "go_to"})
EXIT_INTERNAL = 77
MAX_TEXT = 2000
#: Bytes asked of one ``recv``. Python allocates that much for each call before it knows how much
#: came: below glibc's mmap threshold (128 KiB) that is a cheap heap allocation, above it a new
#: mapping each time (measured: 50 us more a call, with its page faults).
RECV_BYTES = 1 << 16


# --------------------------------------------------------------------------- framing
def _default(obj: Any) -> Any:
    if type(obj) is tuple:
        return list(obj)
    raise TypeError(f"a {type(obj).__name__} object is not plain data "
                    "(use None, bool, int, float, str, bytes, list, dict)")


def _not_plain(task: str, exc: BaseException) -> str:
    """Why the value task ``task`` returned cannot be sent, and what to return instead."""
    text = str(exc)
    if isinstance(exc, ValueError) and "recursion" in text:
        return (f"the value task {task} returned is nested too deeply (lists or dicts inside each other "
                "hundreds of levels down); return a flatter value, e.g. a list of [x, y] pairs")
    if isinstance(exc, OverflowError) or "int too big" in text:
        return (f"task {task} returned an integer too large to send; return it as text (str(n)) or "
                "as a float")
    return (f"task {task} returned something that is not plain data ({_trim(text, 120)}); return "
            "numbers, text, True/False/None, or lists and dicts of them")


_PACKER = msgpack.Packer(use_bin_type=True, strict_types=True, default=_default)
_PACK_LOCK = threading.Lock()  # one packer for all threads (it resets itself after an error)
_unpackb = msgpack.unpackb


def pack(msg: dict) -> bytes:
    """Encode one message (length prefix + msgpack); raises TypeError/ValueError if not plain."""
    with _PACK_LOCK:
        body = _PACKER.pack(msg)
    return HEADER.pack(len(body)) + body


class FrameError(Exception):
    """A frame that breaks the size cap or is not a msgpack map."""


class FrameReader:
    """Accumulates bytes and yields decoded messages; refuses frames over ``cap`` bytes."""

    def __init__(self, cap: int) -> None:
        self.cap = cap
        self.buf = bytearray()

    def feed(self, data: bytes) -> list[dict]:
        """Add received bytes; return the complete messages (raises :class:`FrameError`)."""
        if self.buf:  # a frame began in an earlier piece: go on from the buffer
            self.buf += data
            view: bytes | bytearray = self.buf
        else:  # most often whole frames: read them from ``data`` without copying it first
            view = data
        out = []
        pos, end = 0, len(view)
        cap = self.cap
        while end - pos >= 4:
            (n,) = HEADER.unpack_from(view, pos)
            if n > cap:
                raise FrameError(f"message too large ({n} bytes > {cap} bytes)")
            stop = pos + 4 + n
            if stop > end:
                break
            try:
                msg = _unpackb(view[pos + 4:stop], strict_map_key=False)
            except Exception as exc:
                raise FrameError(f"undecodable message ({type(exc).__name__})") from None
            if type(msg) is not dict or type(msg.get("t")) is not str:
                raise FrameError("message is not a map with a type")
            out.append(msg)
            pos = stop
        if view is self.buf:
            del self.buf[:pos]
        elif pos < end:
            self.buf += memoryview(data)[pos:]
        return out


_FACTORY: Callable[..., dict[str, Any]] | None = None


def _robot_calls() -> Callable[..., dict[str, Any]]:
    """The factory of a robot's remote calls, compiled once from the table (robo_comp/sandbox/api.py)."""
    global _FACTORY
    if _FACTORY is None:
        scope: dict[str, Any] = {}
        exec(compile(_api.factory_source(), "<robot api>", "exec"), scope)
        _FACTORY = scope["_make"]
    return _FACTORY

def _trim(text: str, n: int = MAX_TEXT) -> str:
    return text if len(text) <= n else text[:n] + f"... ({len(text) - n} more characters)"


# --------------------------------------------------------------------------- child state
class _Run:
    """One run (a task or a module load) executing in a worker."""

    __slots__ = ("id", "tag", "file", "output", "violation", "cancelled", "drawing", "key")

    def __init__(self, run_id: int, tag: Any, file: str) -> None:
        self.id = run_id
        self.tag = tag
        self.file = file
        self.output = 0
        self.violation: str | None = None
        self.cancelled = False
        #: The shapes drawn since the last movement call (sent with it: docs/sandbox.md, "Debug drawing").
        self.drawing: list | None = None
        #: The key of the last answer to this run's calls, named by its next call: the parent takes
        #: the time between them as one turn of a loop (its call limiter; sandbox/parent.py).
        self.key = 0


class _Module:
    """A loaded module inside the child: its identity, task functions and globals."""

    __slots__ = ("name", "version", "kind", "file", "sha256", "tasks", "functions", "globals")
    name: str
    version: str
    kind: str
    file: str
    sha256: str
    tasks: dict[str, Any]
    functions: dict[str, Any]
    globals: dict[str, Any]


class Child:
    """The child's state and its message loop (one instance per process)."""

    def __init__(self, sock: socket.socket, limits: dict, replies: socket.socket) -> None:
        from robo_comp.sandbox import contract, policy as restricted  # imported before the limits
        self.contract = contract
        self.restricted = restricted
        self.sock = sock
        #: Answers to robot-API calls come on a socket of their own (:class:`_Replies`).
        self.replies = _Replies(replies, max(limits["message_bytes"], 1 << 20))
        self.limits = limits
        self.send_lock = threading.Lock()
        self.state_lock = threading.Lock()
        self.modules: dict[str, _Module] = {}
        self.task_index: dict[str, str] = {}
        self.calls: dict[int, "_Worker"] = {}
        self.runs: dict[int, _Worker] = {}
        self.next_call = 1
        #: Source lines of every loaded file, so that a refusal quotes the line the student wrote.
        self.sources: dict[str, list[str]] = {}
        self.policy = restricted.Policy(int(limits.get("seed", 0)), self._print_sink)
        self.workers = [_Worker(self, i) for i in range(int(limits["workers"]))]
        #: The workers by thread id (an int: hashed by value, see current_worker).
        self.by_thread = {w.ident: w for w in self.workers}
        self.cpu_soft = -1
        self.cpu_recheck = 0.0  # time.monotonic() after which refresh_cpu reads the CPU time again
        self.stderr_left = 16384

    # ------------------------------------------------------------------ sending
    def send(self, msg: dict) -> None:
        """Send one message to the parent (thread-safe); oversize → :class:`LimitExceeded`."""
        data = pack(msg)
        if len(data) - 4 > self.limits["message_bytes"]:
            raise self.restricted.LimitExceeded(
                f"message too large ({len(data) - 4} bytes > {self.limits['message_bytes']} bytes)")
        with self.send_lock:
            self.sock.sendall(data)

    def refresh_cpu(self) -> None:
        """Give team code ``cpu_seconds`` more CPU from now (the rlimit is a backstop).

        Reading the process's CPU time is a system call; it is read again only once the process
        could have used up the second's rest the soft limit was rounded up by (its threads together
        use at most one CPU second per thread each second), so team code still has at least
        ``cpu_seconds`` from every call."""
        now = time.monotonic()
        if now < self.cpu_recheck:
            return
        budget = float(self.limits["cpu_seconds"])
        used = time.process_time()
        want = int(math.ceil(used + budget))
        if want != self.cpu_soft:
            try:
                resource.setrlimit(resource.RLIMIT_CPU, (want, resource.RLIM_INFINITY))
                self.cpu_soft = want
            except (ValueError, OSError):
                return
        self.cpu_recheck = now + (want - used - budget) / (len(self.workers) + 1)

    # ------------------------------------------------------------------ team output
    def current_worker(self) -> _Worker | None:
        """The worker whose thread this is (None on the main thread). Not a threading.local: its
        per-thread record is hashed the first time a thread uses it, which would take a serial
        number (sandbox/determinism.py) at a moment that depends on which worker is free."""
        return self.by_thread.get(threading.get_ident())

    def current_run(self) -> _Run | None:
        w = self.current_worker()
        return None if w is None else w.current

    def violate(self, run: _Run, message: str) -> None:
        if run.violation is None:
            run.violation = message
            try:
                self.send({"t": "violation", "r": run.id, "message": message})
            except Exception:
                pass
        raise self.restricted.LimitExceeded(message)

    def _print_sink(self, text: str, stream: str = "print") -> None:
        run = self.current_run()
        if run is None:
            return
        if type(text) is not str:
            text = str(text)
        text = self.restricted._determinism.scrub(text)  # no memory addresses in the log
        cap = self.limits["output_bytes"]
        left = cap - run.output
        if left <= 0 or len(text) > left:
            if left > 0:
                run.output = cap
                self.send({"t": "log", "run": run.id, "tag": run.tag, "stream": stream,
                           "text": text[:left]})
            self.violate(run, f"output limit ({cap // 1024} KiB) exceeded")
        run.output += len(text)
        chunk = 8192
        for i in range(0, len(text), chunk):
            self.send({"t": "log", "run": run.id, "tag": run.tag, "stream": stream,
                       "text": text[i:i + chunk]})

    # ------------------------------------------------------------------ robot API
    def rpc(self, tag: Any, name: str, args: list) -> Any:
        """One robot-API call from team code: send it, then read the answer from the reply socket
        in this worker itself (:class:`_Replies`)."""
        R = self.restricted
        worker = self.current_worker()
        run = None if worker is None else worker.current
        if run is None or worker is None:
            raise R.RobotError("the robot API is only usable while a task or init runs")
        if run.cancelled:
            raise R.TaskCancelled("the task was cancelled")
        if tag is None:
            raise R.RobotError(f"{name}: no robot is attached (init without a robot)")
        if name in _MOVEMENT:
            self.flush_drawing(run)
        call_id = -1
        try:
            with self.state_lock:
                call_id = self.next_call
                self.next_call += 1
                self.calls[call_id] = worker
                # From here the main thread raises no TaskCancelled in this thread (it could cut a
                # frame in half while this thread reads the socket): the parent answers a call of a
                # cancelled run with "cancelled" instead. One raised just before is taken back.
                worker.waiting = True
                raised, worker.raised = worker.raised, False
            if raised:
                _take_back_async_exc(worker.ident)
            self.send({"t": "call", "c": call_id, "r": run.id, "g": tag, "n": name, "a": args, "k": run.key})
        except BaseException as exc:
            with self.state_lock:
                self.calls.pop(call_id, None)
                worker.waiting = False
            if isinstance(exc, R.LimitExceeded):
                self.violate(run, str(exc))
            if isinstance(exc, (TypeError, ValueError, OverflowError)):
                raise R.RobotError(f"{name}: arguments are not plain data: {_trim(str(exc), 200)}") from None
            raise
        reply = self.replies.wait(call_id, self.calls)
        key = reply.get("k")
        run.key = key if type(key) is int else 0
        with self.state_lock:
            self.calls.pop(call_id, None)
            worker.waiting = False
            cancelled = run.cancelled
        self.refresh_cpu()
        if reply.get("x") or cancelled:
            run.cancelled = True
            raise R.TaskCancelled(str(reply.get("e", "cancelled")) if reply.get("x") else "the task was cancelled")
        if reply.get("ok"):
            return reply.get("v")
        raise R.RobotError(f"{name}: {_trim(str(reply.get('e', 'refused')), 500)}")

    def flush_drawing(self, run: _Run, clear: bool = True) -> None:
        """Send the shapes ``run`` drew since its last movement call: the robot's new frame (an
        empty one clears a frame it sent before, unless not ``clear``). One message, no answer awaited."""
        shapes = run.drawing
        if shapes is None or run.tag is None or not (shapes or clear):
            return
        run.drawing = [] if shapes else None
        self.send({"t": "draw", "r": run.id, "s": shapes})

    def make_robot(self, tag: Any) -> Any:
        """The ``robot`` object team functions get: read-only, plain functions only."""
        rpc = self.rpc
        sink = self._print_sink

        def _num(v: Any, what: str) -> Any:
            if type(v) not in (int, float):
                raise TypeError(f"{what} must be a number")
            return v

        remote = _robot_calls()(rpc, tag, _num)  # the table's calls (robo_comp/sandbox/api.py)

        def log(text):
            """Write a line to the team's log (counts against the output limit)."""
            sink(str(text) + "\n", "log")

        current = self.current_run

        def _draw(shape: list) -> bool:
            run = current()
            if run is None or tag is None:
                return False
            if run.drawing is None:
                run.drawing = []
            if len(run.drawing) >= _drawing.MAX_SHAPES:
                return False
            run.drawing.append(shape)
            return True

        def draw_dot(x, y, colour="yellow"):
            """Draw a dot at cell (x, y) on your team's view (debug drawing: costs nothing; False when
            this frame already holds the most shapes)."""
            return _draw(_drawing.dot(x, y, colour))

        def draw_line(x0, y0, x1, y1, colour="yellow"):
            """Draw a line from cell (x0, y0) to (x1, y1) on your team's view (debug drawing)."""
            return _draw(_drawing.line(x0, y0, x1, y1, colour))

        def draw_text(x, y, text, colour="white"):
            """Write a short text at cell (x, y) on your team's view (debug drawing; cut to 32 characters)."""
            return _draw(_drawing.text(x, y, text, colour))

        local = {f.__name__: f for f in (log, draw_dot, draw_line, draw_text)}
        items = {c.name: remote[c.name] if not c.local else local[c.name] for c in _api.ROBOT_API}
        items["tag"] = tag
        return self.restricted.Namespace("robot", items)

    # ------------------------------------------------------------------ message loop
    def serve(self) -> None:
        """Read and dispatch parent messages until the parent goes away."""
        reader = FrameReader(max(self.limits["message_bytes"], 1 << 20))
        recv = self.sock.recv
        # Wait in poll, not in recv: a thread asleep in recv on a UNIX socket is also woken each
        # time the parent reads what this process sent on it (the kernel's "room to write" wake-up
        # is not filtered for readers), i.e. at every robot-API call; poll sleeps through those.
        poller = select.poll()
        poller.register(self.sock.fileno(), select.POLLIN)
        while True:
            poller.poll()
            data = recv(RECV_BYTES)
            if not data:
                os._exit(0)
            for msg in reader.feed(data):
                self.dispatch(msg)

    def dispatch(self, msg: dict) -> None:
        t = msg["t"]
        if t == "run":
            self.refresh_cpu()
            self._start(msg, "task")
        elif t == "load":
            self.refresh_cpu()
            self._start(msg, "load")
        elif t == "cancel":
            self._cancel(msg.get("r"))
        elif t == "unload":
            name = msg.get("name")
            with self.state_lock:
                if self.modules.pop(str(name), None) is not None:
                    self._reindex()
            self.send({"t": "unloaded", "name": name})
        else:
            os._exit(EXIT_PROTOCOL)

    def _start(self, msg: dict, kind: str) -> None:
        for w in self.workers:
            if w.run is None:
                run = _Run(msg["r"], msg.get("g"), msg.get("file", ""))
                with self.state_lock:
                    w.run = run
                    self.runs[run.id] = w
                w.jobs.put((kind, run, msg))
                return
        self.send({"t": "failed", "r": msg["r"], "why": "error", "line": None,
                   "m": "too many concurrent runs in this sandbox"})

    def _cancel(self, run_id: Any) -> None:
        with self.state_lock:
            w = self.runs.get(run_id)
            if w is None or w.run is None or w.run.id != run_id:
                return
            w.run.cancelled = True
            if w.in_team and not w.waiting and _async_exc is not None and w.ident is not None:
                w.raised = True
                _async_exc(w.ident, self.restricted.TaskCancelled)

    def _reindex(self) -> None:
        self.task_index = {t: m.name for m in self.modules.values() for t in m.tasks}

    # ------------------------------------------------------------------ helpers for runs
    def team_traceback(self, exc: BaseException) -> list[str]:
        """The frames of team files an exception went through, outermost first, as
        ``file:line in function: code`` (at most 20; call before :meth:`describe` clears them)."""
        out = []
        tb = exc.__traceback__
        while tb is not None:
            code = tb.tb_frame.f_code
            lines = self.sources.get(code.co_filename)
            if lines is not None:
                n = tb.tb_lineno
                text = lines[n - 1].strip() if 0 < n <= len(lines) else ""
                out.append(f"{code.co_filename}:{n} in {code.co_name}: {text[:120]}")
            tb = tb.tb_next
        return out[-20:]

    def describe(self, exc: BaseException, file: str) -> tuple[str, int | None]:
        """``'file:line: Type: message'`` for an exception raised by team code."""
        line = None
        tb = exc.__traceback__
        while tb is not None:
            frame = tb.tb_frame
            if frame.f_code.co_filename == file:
                line = tb.tb_lineno
            try:
                frame.clear()  # drop team locals at once (a memory hog must be freed first)
            except RuntimeError:
                pass  # a frame still running (ours)
            tb = tb.tb_next
        exc.__traceback__ = None
        exc.__context__ = None
        try:
            text = str(exc)
        except BaseException:
            text = ""
        name = type(exc).__name__
        if isinstance(exc, MemoryError):
            return (f"memory limit ({self.limits['memory_mib']} MiB) exceeded: your code kept too much data; "
                    "keep fewer or smaller lists and dicts (e.g. one set of visited cells)"), line
        if isinstance(exc, self.restricted.LimitExceeded):
            return text, line
        if isinstance(exc, RecursionError):
            text = "maximum recursion depth exceeded (deep recursion)"
        msg = f"{name}: {_trim(text, 500)}" if text else name
        code = self.sources.get(file, [])[line - 1] if line and 0 < line <= len(self.sources.get(file, [])) else ""
        quoted = f"{explain.quote(code)}: " if code.strip() else ""
        where = f"{file}:{line}: {quoted}" if line else (f"{file}: " if file else "")
        return where + msg, line


_async_exc: Callable[[int, type], None] | None = None
_clear_async_exc: Callable[[int, None], Any] | None = None


def _install_async_exc() -> None:
    global _async_exc, _clear_async_exc
    try:
        import ctypes
        set_exc = ctypes.pythonapi.PyThreadState_SetAsyncExc
        set_exc.argtypes = (ctypes.c_ulong, ctypes.py_object)

        def raise_in(ident: int, exc: type) -> None:
            set_exc(ident, exc)
        _async_exc = raise_in
        # the same function with a NULL exception: takes back one not yet raised
        _clear_async_exc = ctypes.PYFUNCTYPE(ctypes.c_int, ctypes.c_ulong, ctypes.c_void_p)(
            ("PyThreadState_SetAsyncExc", ctypes.pythonapi))
    except Exception:  # pragma: no cover - ctypes missing
        _async_exc = _clear_async_exc = None


def _take_back_async_exc(ident: int | None) -> None:
    """Take back an exception the main thread set for thread ``ident`` that has not fired yet."""
    if _clear_async_exc is not None and ident is not None:
        _clear_async_exc(ident, None)


class _Replies:
    """The answers to robot-API calls, on a socket of their own, read by the workers waiting for
    them: the worker that made a call reads its answer itself, with no hand-over from another
    thread, so a call costs what a bare call and answer between two processes costs. One waiting
    worker reads at a time; an answer it reads for another waiting worker is left for that one,
    which is woken. A worker waiting here cannot be interrupted (see :meth:`Child.rpc`)."""

    def __init__(self, sock: socket.socket, cap: int) -> None:
        self.recv = sock.recv
        self.reader = FrameReader(cap)
        self.lock = threading.Lock()
        self.cond = threading.Condition(self.lock)  # (entered through the lock: cheaper)
        self.reading = False
        self.got: dict[int, dict] = {}
        self.waiters = 0

    def wait(self, call_id: int, awaited: dict[int, Any]) -> dict:
        """Block until the answer to ``call_id`` has come; ``awaited`` holds the call ids some
        worker waits for (answers to other calls are dropped)."""
        with self.lock:
            while True:
                mine = self.got.pop(call_id, None)
                if mine is not None:
                    return mine
                if not self.reading:
                    self.reading = True
                    break
                self.waiters += 1
                self.cond.wait()
                self.waiters -= 1
        try:
            while mine is None:
                data = self.recv(RECV_BYTES)
                if not data:
                    os._exit(0)
                others = {}
                for msg in self.reader.feed(data):
                    c = msg.get("c")
                    if msg["t"] != "reply" or type(c) is not int:
                        os._exit(EXIT_PROTOCOL)
                    if c == call_id:
                        mine = msg
                    elif c in awaited:
                        others[c] = msg
                    # else: an answer to a call no worker made (one forged below the policy): dropped
                if others:
                    with self.lock:
                        self.got.update(others)
                        self.cond.notify_all()
        except FrameError:
            os._exit(EXIT_PROTOCOL)
        except MemoryError:
            os._exit(EXIT_MEMORY)
        finally:
            with self.lock:
                self.reading = False
                if self.waiters:
                    self.cond.notify_all()  # one of them reads now
        assert mine is not None  # (the loop above ends only with it)
        return mine


class _Worker:
    """A pre-started thread that runs one run at a time (threads cannot be made later)."""

    def __init__(self, child: Child, index: int) -> None:
        self.child = child
        self.jobs: "queue.SimpleQueue[tuple]" = queue.SimpleQueue()
        self.run: _Run | None = None
        #: The run this thread executes now (set by the thread itself; ``run`` is the main
        #: thread's booking).
        self.current: _Run | None = None
        self.in_team = False
        #: In a robot-API call, waiting for its answer (no TaskCancelled is raised in the thread then).
        self.waiting = False
        #: The main thread raised TaskCancelled in this thread (it may not have fired yet).
        self.raised = False
        self.sent = False
        self.thread = threading.Thread(target=self.loop, name=f"team-{index}", daemon=True)
        self.thread.start()
        self.ident = self.thread.ident

    def finish(self, msg: dict) -> None:
        """Send the final message of the run exactly once and free the worker."""
        c = self.child
        if self.sent:
            return
        self.sent = True
        if self.run is not None and msg.get("t") in ("done", "failed"):
            try:
                c.flush_drawing(self.run, clear=False)  # what the task drew last stays on screen
            except Exception:
                pass
        try:
            c.send(msg)
        except Exception:
            c.send({"t": "failed", "r": msg.get("r"), "why": "error", "line": None,
                    "m": "could not send the outcome"})

    def loop(self) -> None:
        c = self.child
        while True:
            try:
                kind, run, msg = self.jobs.get()
            except BaseException:
                continue
            self.sent = False
            self.current = run
            try:
                if kind == "task":
                    self.run_task(run, msg)
                else:
                    self.run_load(run, msg)
            except BaseException as exc:  # a late async cancel or a bug: still answer once
                try:
                    cancelled = isinstance(exc, c.restricted.TaskCancelled)
                    text = "cancelled" if cancelled else \
                        f"internal error in the sandbox: {type(exc).__name__}: {_trim(str(exc), 200)}"
                    if kind == "load":
                        self.finish({"t": "load_failed", "r": run.id, "rule": "internal",
                                     "line": None, "m": text, "file": str(msg.get("file"))[:80]})
                    else:
                        self.finish({"t": "failed", "r": run.id, "line": None, "m": text,
                                     "why": "cancelled" if cancelled else "error"})
                except BaseException:
                    pass
            finally:
                self.in_team = False
                for _attempt in range(100):
                    try:
                        with c.state_lock:
                            self.run = None
                            c.runs.pop(run.id, None)
                            for k in [k for k, w in c.calls.items() if w is self]:
                                del c.calls[k]
                        self.waiting = False
                        self.current = None
                        break
                    except BaseException:
                        continue

    def _team_call(self, fn: Callable, *args: Any) -> Any:
        with self.child.state_lock:
            self.in_team = True
            cancelled = self.run is not None and self.run.cancelled
        try:
            if cancelled:
                raise self.child.restricted.TaskCancelled("the task was cancelled")
            return fn(*args)
        finally:
            with self.child.state_lock:
                self.in_team = False

    # -------------------------------------------------------------- a task
    def run_task(self, run: _Run, msg: dict) -> None:
        c = self.child
        R = c.restricted
        module = c.modules.get(msg.get("module", "")) or c.modules.get(c.task_index.get(msg["task"], ""))
        if module is None or msg["task"] not in module.functions:
            self.finish({"t": "failed", "r": run.id, "why": "error", "line": None,
                         "m": f"no loaded module provides task {msg['task']!r}"})
            return
        run.file = module.file
        fn = module.functions[msg["task"]]
        robot = c.make_robot(run.tag)
        try:
            result = self._team_call(fn, robot, *msg.get("a", []))
        except BaseException as exc:
            why = "cancelled" if isinstance(exc, R.TaskCancelled) else "error"
            if isinstance(exc, (MemoryError, R.LimitExceeded)):
                why = "limit"
            trace = c.team_traceback(exc) if why == "error" else []
            text, line = c.describe(exc, module.file)
            del exc
            if run.violation:
                why, text = "limit", run.violation
            elif run.cancelled and why == "error":
                why = "cancelled"
            self.finish({"t": "failed", "r": run.id, "why": why, "line": line, "m": text, "tb": trace})
            return
        if run.violation:
            self.finish({"t": "failed", "r": run.id, "why": "limit", "line": None,
                         "m": run.violation})
            return
        if run.cancelled:
            self.finish({"t": "failed", "r": run.id, "why": "cancelled", "line": None,
                         "m": "cancelled"})
            return
        try:
            data = pack({"t": "done", "r": run.id, "v": result})
        except (TypeError, ValueError, OverflowError) as exc:
            self.finish({"t": "failed", "r": run.id, "why": "error", "line": None,
                         "m": f"{module.file}: {_not_plain(msg['task'], exc)}"})
            return
        cap = c.limits["result_bytes"]
        if len(data) - 4 > cap:
            self.finish({"t": "failed", "r": run.id, "why": "limit", "line": None,
                         "m": f"result too large ({len(data) - 4} bytes > {cap} bytes)"})
            return
        self.sent = True
        with c.send_lock:
            c.sock.sendall(data)

    # -------------------------------------------------------------- a module load
    def run_load(self, run: _Run, msg: dict) -> None:
        c = self.child
        C, R = c.contract, c.restricted
        file = str(msg.get("file", "?"))[:80]

        def fail(rule: str, detail: str, line: int | None = None) -> None:
            self.finish({"t": "load_failed", "r": run.id, "rule": rule, "line": line,
                         "m": _trim(detail, 1000), "file": file})

        try:
            C.check_filename(msg.get("file"))
            source = C.check_source(msg.get("src"))
            self.child.sources[file] = source.splitlines()
            code = R.compile_team(source, file)
            tree = ast.parse(source, file)
            C.check_imports(tree)
            manifest = C.read_manifest(tree)
            C.check_signatures(tree, manifest)
        except C.ContractError as exc:
            fail(exc.rule, exc.detail, exc.line)
            return
        except R.PolicyError as exc:
            fail(exc.rule, exc.detail, exc.line)
            return
        except (SyntaxError, RecursionError, MemoryError, ValueError) as exc:
            fail("syntax", f"{type(exc).__name__}: {exc}", getattr(exc, "lineno", None))
            return
        name = manifest["name"]
        builtin = set(msg.get("builtin", ()))
        for tname in manifest["tasks"]:
            owner = c.task_index.get(tname)
            if owner is not None and owner != name:
                fail("conflict", f"task {tname!r} is already provided by module {owner!r} "
                                 f"(unload it first)")
                return
            if manifest["kind"] == "extension" and tname in builtin:
                fail("conflict", f"an extension may not replace built-in task {tname!r}; "
                                 f"declare kind \"code\" to replace its behaviour")
                return
        glb = c.policy.make_globals(f"team.{name}")
        run.file = file
        try:
            self._team_call(exec, code, glb)
        except BaseException as exc:
            text, line = c.describe(exc, file)
            del exc
            fail("limit" if run.violation else "module",
                 run.violation or f"running the module body failed: {text}", line)
            return
        functions: dict[str, types.FunctionType] = {}
        for tname, spec in manifest["tasks"].items():
            fn = glb.get(tname)
            want = ["robot"] + [a["name"] for a in spec["args"]]
            if not _is_own_function(fn, file, want):
                fail("signature", f"after running the module, {tname!r} is not the function "
                                  f"def {tname}({', '.join(want)})")
                return
            functions[tname] = fn
        init = glb.get("init")
        if init is not None:
            if not _is_own_function(init, file, ["robot"]):
                fail("signature", "init must be a function def init(robot)")
                return
            c.send({"t": "phase", "r": run.id, "phase": "init"})
            try:
                self._team_call(init, c.make_robot(run.tag))
            except BaseException as exc:
                text, line = c.describe(exc, file)
                del exc
                fail("limit" if run.violation else "init",
                     run.violation or f"init(robot) failed: {text}", line)
                return
        if run.cancelled:
            fail("init", "the load was cancelled")
            return
        m = _Module()
        m.name, m.version, m.kind, m.file = name, manifest["version"], manifest["kind"], file
        m.sha256 = C.source_hash(source)
        m.tasks, m.functions, m.globals = manifest["tasks"], functions, glb
        with c.state_lock:
            previous = c.modules.get(name)
            c.modules[name] = m
            c._reindex()
        self.finish({"t": "loaded", "r": run.id, "name": name, "version": m.version,
                     "kind": m.kind, "file": file, "sha256": m.sha256, "tasks": m.tasks,
                     "description": manifest["description"],
                     "previous": previous.version if previous else None})


def _is_own_function(fn: Any, file: str, params: list[str]) -> TypeGuard[types.FunctionType]:
    if type(fn) is not types.FunctionType:
        return False
    code = fn.__code__
    return (code.co_filename == file and code.co_argcount == len(params)
            and list(code.co_varnames[:code.co_argcount]) == params
            and not fn.__defaults__ and not (code.co_flags & 0x0C))


# --------------------------------------------------------------------------- process set-up
class _CappedStream:
    """Replaces sys.stdout/stderr in the child: forwards to the parent, capped."""

    def __init__(self, child: "Child | None", stream: str) -> None:
        self.child = child
        self.stream = stream

    def write(self, text: str) -> int:
        c = self.child
        if c is None or c.stderr_left <= 0:
            return len(text)
        text = text[:c.stderr_left]
        c.stderr_left -= len(text)
        try:
            c.send({"t": "log", "run": None, "tag": None, "stream": self.stream, "text": text})
        except Exception:
            pass
        return len(text)

    def flush(self) -> None:
        pass


_WARM_UP = '''
MANIFEST = {"name": "warm", "version": "1", "kind": "code", "tasks": {"t": {"args": []}}}
import math, random, heapq
class \uff23ounter:
    def __init__(self):
        self.n = 0
def t(robot):
    a, (b, c) = 1, [2, "\\d"]
    print(f"{a!r:>{3}} {b:.2f} %s" % c, [x for x in range(3)], {1: 2}, {3})
    try:
        raise ValueError("x")
    except ValueError as e:
        return str(e)
'''


def _warm_up(child: "Child") -> None:
    """Trigger every lazy import of the compile/check/run path before the file limit."""
    import encodings.idna  # noqa: F401
    import linecache  # noqa: F401
    import unicodedata  # noqa: F401  (NFKC normalisation of non-ASCII identifiers)
    import warnings  # noqa: F401  (SyntaxWarning while compiling)
    import ast as _ast
    C, R = child.contract, child.restricted
    code = R.compile_team(_WARM_UP, "warm.py")
    tree = _ast.parse(_WARM_UP)
    C.check_imports(tree)
    C.check_signatures(tree, C.read_manifest(tree))
    glb = R.Policy(0, lambda text: None).make_globals("team.warm")
    exec(code, glb)
    glb["t"](None)
    child.describe(ValueError("warm"), "warm.py")
    pack({"t": "warm", "v": [1, 2.0, "x", b"y", None, True, {"k": (1, 2)}]})


def _die_with_parent() -> None:
    try:
        import ctypes
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG
        libc.prctl(38, 1, 0, 0, 0)  # PR_SET_NO_NEW_PRIVS
    except Exception:
        pass


def _drop_root() -> None:
    if os.geteuid() != 0:
        return
    try:
        os.setgroups([])
        os.setgid(65534)
        os.setuid(65534)
    except OSError:
        pass


def _no_new_programs(seccomp: list | None, debug: bool) -> None:
    """Inside the OS layer: install the run filter (no ``execve`` from now on) on every thread
    (sandbox/sysfilter.py). Team code never runs without it: a refusal ends the child."""
    if seccomp is None:
        return
    try:
        sysfilter.install(bytes(seccomp[0]), int(seccomp[1]))
    except OSError:
        if debug:
            import traceback
            traceback.print_exc(file=sys.__stderr__)
        os._exit(EXIT_INTERNAL)


def _set_limits(limits: dict, keep_fds: int) -> None:
    mib = 1024 * 1024

    def lim(which: int, soft: int, hard: int | None = None) -> None:
        try:
            resource.setrlimit(which, (soft, soft if hard is None else hard))
        except (ValueError, OSError):
            pass

    lim(resource.RLIMIT_CORE, 0)
    lim(resource.RLIMIT_FSIZE, 0)
    lim(resource.RLIMIT_NPROC, 0)
    lim(resource.RLIMIT_NOFILE, keep_fds)
    lim(resource.RLIMIT_AS, int(limits["memory_mib"]) * mib)
    lim(resource.RLIMIT_CPU, int(math.ceil(time.process_time() + float(limits["cpu_seconds"]))),
        resource.RLIM_INFINITY)


#: personality(2) flag: no address-space layout randomisation.
ADDR_NO_RANDOMIZE = 0x0040000


def _without_aslr() -> None:
    """Start this process again with address randomisation off (a replayable child, as a spare:
    the seal already keeps every address from team code, see
    :mod:`robo_comp.sandbox.determinism`; ``ROBO_COMP_SANDBOX_ASLR=1`` skips this).
    Returns only when it is already off or the kernel does not let us turn it off."""
    try:
        import ctypes
        libc = ctypes.CDLL(None, use_errno=True)
        libc.personality.restype = ctypes.c_int
        libc.personality.argtypes = [ctypes.c_ulong]
        now = libc.personality(0xFFFFFFFF)
        if now < 0 or now & ADDR_NO_RANDOMIZE:
            return
        if libc.personality(now | ADDR_NO_RANDOMIZE) < 0 or not libc.personality(0xFFFFFFFF) & ADDR_NO_RANDOMIZE:
            return
    except Exception:
        return
    os.execv(sys.executable, list(sys.orig_argv))


def _plant_hole(child: "Child") -> None:
    """Tests only: every team module's builtins get the real ``os``, ``socket`` and ``ctypes``
    modules (a hole in the policy, to show what the OS layer still stops: ``ctypes`` makes any
    system call)."""
    import ctypes
    make = child.policy.make_globals

    def holed(module_name: str) -> dict[str, Any]:
        glb = make(module_name)
        glb["__builtins__"].update(os=os, socket=socket, ctypes=ctypes)
        return glb

    child.policy.make_globals = holed  # type: ignore[method-assign]


def _lowest(fd: int) -> int:
    """``fd`` moved to the lowest free descriptor: keeps RLIMIT_NOFILE small whatever the parent had open."""
    low = os.dup(fd)
    if low < fd:
        os.close(fd)
        return low
    os.close(low)
    return fd


def main(argv: list[str] | None = None) -> None:
    """Child entry point (``python -m robo_comp.sandbox.child``)."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--fd", type=int, required=True)
    ap.add_argument("--replies", type=int, required=True, help="the socket the call answers come on")
    ap.add_argument("--limits", required=True)
    opts = ap.parse_args(argv)
    limits = msgpack.unpackb(bytes.fromhex(opts.limits), raw=False)
    from robo_comp.sandbox import determinism
    if limits.get("replayable") and not determinism.sealed():
        print(f"sandbox: cannot keep memory addresses from team code on this Python "
              f"({determinism._seal_error}); a replayable sandbox does not run without that", file=sys.stderr)
        os._exit(EXIT_INTERNAL)
    if limits.get("aslr_off") and argv is None:
        _without_aslr()
    fd = _lowest(opts.fd)
    sock = socket.socket(fileno=fd)
    sock.setblocking(True)
    replies = socket.socket(fileno=_lowest(opts.replies))
    replies.setblocking(True)
    replies.shutdown(socket.SHUT_WR)  # answers only come in
    _die_with_parent()
    try:
        os.nice(int(limits.get("nice", 0)))
    except OSError:
        pass
    _install_async_exc()
    child = Child(sock, limits, replies)  # imports the policy and starts the workers
    if limits.get("test_policy_hole"):  # tests only (Limits.test_policy_hole): the real modules
        _plant_hole(child)
    _warm_up(child)
    sys.stdout = _CappedStream(child, "stdout")
    sys.stderr = _CappedStream(child, "stderr")
    _drop_root()
    _no_new_programs(limits.get("seccomp"), limits.get("debug", False))
    _set_limits(limits, keep_fds=max(fd, replies.fileno()) + 1)
    child.cpu_soft, child.cpu_recheck = -1, 0.0
    child.refresh_cpu()
    child.send({"t": "ready", "pid": os.getpid()})
    try:
        child.serve()
    except MemoryError:
        os._exit(EXIT_MEMORY)
    except FrameError:
        os._exit(EXIT_PROTOCOL)
    except BaseException:
        if limits.get("debug"):
            import traceback
            traceback.print_exc(file=sys.__stderr__)
        os._exit(EXIT_INTERNAL)


if __name__ == "__main__":
    main()
