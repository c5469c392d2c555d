"""Where league matches are played: in this process, on a local process pool, or on Ray.

Every runner takes match specs (plain data, see :func:`robo_comp.league.engine.play_match`)
and calls ``on_result(spec, result)`` or ``on_error(spec, message)`` as matches end, in the
order they end. A match is deterministic, so where it ran does not change its result.

* :class:`LocalRunner` — ``workers`` processes of the run's own (one worker: played in this
  process). The workers are started with ``spawn`` (no inherited threads or sockets), so a
  script that uses more than one needs the usual ``if __name__ == "__main__":`` guard; a
  worker that dies costs only its own match, which is played again. Each worker is a session
  of its own (Linux gives each session an equal share of the CPU, so workers that shared the
  run's session would share one share between them), warms up (imports, compiled planner
  kernels) as soon as it starts, and stays up for the runner's next run until :meth:`close`
  (a Swiss season plays a run a round);
* :class:`RayRunner` — each match a Ray task of 1 CPU on a Ray cluster (``ray.init(address)``:
  ``"auto"`` joins the cluster this machine belongs to, ``"local"`` starts one here). A task
  whose worker dies mid-match (a node lost, a ``kill -9``) is run again by Ray
  (``max_retries``), and gives the same result. The match's event log comes back with its
  result and is written here, so every log lands in the league folder whichever machine
  played the match.
"""
from __future__ import annotations

import multiprocessing
import tempfile
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from robo_comp.league.engine import play_match
from robo_comp.private_files import private_dir, write_private

OnResult = Callable[[dict[str, Any], dict[str, Any]], None]
OnError = Callable[[dict[str, Any], str], None]
#: How often Ray runs a match again after its worker died.
RAY_RETRIES = 3


#: How often a local match whose worker died is played again (like Ray's retries).
LOCAL_RETRIES = 3


class Stopped(Exception):
    """The run was stopped (Ctrl-C): ``running`` matches were stopped mid-way, ``waiting``
    had not started; both are to be played again by the next ``league run``."""

    def __init__(self, running: int, waiting: int) -> None:
        super().__init__(f"stopped: {running} running, {waiting} waiting")
        self.running = running
        self.waiting = waiting


def _worker_main(conn: Any) -> None:
    """A local worker: plays the specs it is sent, one at a time, and sends back
    ``("ok", result)`` or ``("error", traceback)``. It dies with the run (PR_SET_PDEATHSIG) and
    leaves Ctrl-C to the run, which stops it. A session of its own (see the module docstring);
    it warms up before its first match."""
    import os
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # already ignored since its start (see _Worker)
    try:
        import ctypes

        ctypes.CDLL(None).prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG: no orphan after a kill -9 of the run
    except Exception:
        pass
    try:
        os.setsid()  # its own CPU share under the kernel's autogroup scheduling
    except OSError:
        pass
    warm_up()
    while True:
        try:
            spec = conn.recv()
        except EOFError:
            return
        if spec is None:
            return
        try:
            conn.send(("ok", play_match(spec)))
        except Exception:
            conn.send(("error", traceback.format_exc(limit=5)))


def warm_up() -> None:
    """What every match needs before it plays, done once per worker: the engine's imports and
    the planner's compiled kernels (loaded from numba's cache on disk)."""
    try:
        import numpy as np

        import robo_comp.engine.bench  # noqa: F401  (the engine and what it imports)
        from robo_comp.world.planner import find_path

        find_path(np.zeros((8, 8), dtype=bool), (0, 0), (7, 7))
    except Exception:  # a match that needs them fails with the real error
        pass


class _Worker:
    """One local worker process and the match it plays."""

    def __init__(self, ctx: Any) -> None:
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker_main, args=(child,), daemon=True, name="robo-comp-league-worker")
        import signal

        # The worker starts with Ctrl-C ignored (inherited through exec; a spawned child's signal mask
        # is reset, so blocking alone would not do): a press while it starts up is the run's alone.
        # The run blocks it meanwhile as well: on Linux a blocked signal stays pending even while
        # ignored, and is delivered to the run's own handler once restored and unblocked (ignored
        # alone, a press in this window was lost and the run played on).
        # multiprocessing's resource tracker, started with the first spawned process, unblocks SIGINT
        # after its own start: started before, it leaves the mask below alone
        from multiprocessing import resource_tracker

        resource_tracker.ensure_running()
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            old = signal.signal(signal.SIGINT, signal.SIG_IGN)
        except ValueError:  # not the main thread: the worker ignores it once it runs
            old = None
        try:
            self.proc.start()
        finally:
            if old is not None:
                signal.signal(signal.SIGINT, old)
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        child.close()
        self.spec: dict[str, Any] | None = None

    def stop(self) -> None:
        """Kill the process at once (its sandbox children die with it)."""
        if self.proc.is_alive():
            self.proc.kill()
        self.proc.join(5)
        self.conn.close()


class LocalRunner:
    """Matches on ``workers`` local processes (1: in this process).

    The workers are the run's own processes (not a process pool): a worker that dies (a
    ``kill -9``, the OOM killer) costs only the match it played, which is played again on a
    fresh worker, up to :data:`LOCAL_RETRIES` times, with the same result; the other matches
    go on. Workers die with the run (no orphans after any kill of ``league run``), ignore
    Ctrl-C, and are killed at once when the run is stopped (:class:`Stopped`). Otherwise they
    stay up, warm, for the next :meth:`run` until :meth:`close`."""

    def __init__(self, workers: int = 1) -> None:
        self.workers = max(1, int(workers))
        #: Matches played again after their worker died (match id → times).
        self.replayed: dict[Any, int] = {}
        #: What the matches played here cost: ``(teams, scenario, result)``; a free worker takes
        #: the longest expected match left (:func:`robo_comp.league.schedule.longest_first`).
        self.history: list[tuple[list[str], str, dict[str, Any]]] = []
        self._pool: list[_Worker] = []

    @property
    def slots(self) -> int:
        """How many matches run at once."""
        return self.workers

    def run(self, specs: list[dict[str, Any]], on_result: OnResult, on_error: OnError) -> None:
        """Play every spec; report each as it ends. Ctrl-C raises :class:`Stopped`."""
        if self.workers == 1:
            for k, spec in enumerate(specs):
                try:
                    result = play_match(spec)
                except KeyboardInterrupt:
                    raise Stopped(1, len(specs) - k - 1) from None
                except Exception:
                    on_error(spec, traceback.format_exc(limit=5))
                    continue
                on_result(spec, result)
            return
        from multiprocessing.connection import wait as wait_any

        ctx = multiprocessing.get_context("spawn")  # a clean interpreter: no inherited threads or sockets
        todo = list(specs)
        pool = self._pool
        done = False
        try:
            while len(pool) < min(self.workers, len(todo)):
                pool.append(_Worker(ctx))
            while todo or any(w.spec is not None for w in pool):
                for k, w in enumerate(pool):
                    if w.spec is None and todo:
                        if not w.proc.is_alive():  # died while idle: nothing of ours was lost
                            w.stop()
                            pool[k] = w = _Worker(ctx)
                        w.spec = self._next(todo)
                        try:
                            w.conn.send(w.spec)
                        except OSError:  # it died just now: the next wait sees it and plays the match again
                            pass
                busy = [w for w in pool if w.spec is not None]
                ready = wait_any([w.conn for w in busy] + [w.proc.sentinel for w in busy])
                for w in list(busy):
                    played = w.spec
                    assert played is not None
                    if w.conn in ready:
                        try:
                            kind, value = w.conn.recv()
                        except Exception:  # EOF, or a result cut off by the worker's death
                            kind, value = "died", None
                    elif w.proc.sentinel in ready:
                        kind, value = "died", None
                    else:
                        continue
                    if kind == "died":  # only this match is lost: a fresh worker plays it again
                        code = w.proc.exitcode
                        w.stop()
                        pool[pool.index(w)] = fresh = _Worker(ctx)
                        n = self.replayed.get(played.get("id"), 0)
                        if n < LOCAL_RETRIES:
                            self.replayed[played.get("id")] = n + 1
                            fresh.spec = played
                            try:
                                fresh.conn.send(played)
                            except OSError:
                                pass  # seen dead at the next wait
                        else:
                            on_error(played, f"the worker playing this match died {n + 1} times (last exit code {code})")
                        continue
                    w.spec = None
                    if kind == "ok":
                        self.history.append(([e["team"] for e in played.get("entrants", ())],
                                             str(played.get("scenario")), value))
                        on_result(played, value)
                    else:
                        on_error(played, str(value))
            done = True
        except KeyboardInterrupt:
            running = sum(1 for w in pool if w.spec is not None)
            raise Stopped(running, len(todo)) from None
        finally:
            if not done:  # stopped (or broken): no worker outlives it
                self.close()

    def _next(self, todo: list[dict[str, Any]]) -> dict[str, Any]:
        """The spec a free worker plays next: the longest expected from what this runner's matches
        cost so far (in the given order until it knows)."""
        if self.history and len(todo) > 1:
            from robo_comp.league.schedule import longest_first

            first = longest_first(todo, self.history)[0]
            todo.remove(first)
            return first
        return todo.pop(0)

    def close(self) -> None:
        """End the workers (they stay up between runs)."""
        pool, self._pool = self._pool, []
        for w in pool:
            w.stop()

    def __enter__(self) -> "LocalRunner":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def play_match_returning_log(spec: dict[str, Any]) -> tuple[dict[str, Any], bytes | None]:
    """Play ``spec`` with its event log written to a folder of this machine's own, and return
    the result with the log's bytes (a Ray worker may be on a machine without the league folder)."""
    if not spec.get("log"):
        return play_match(spec), None
    with tempfile.TemporaryDirectory(prefix="robo-comp-match-") as d:
        result = play_match(dict(spec, log=str(Path(d) / "events.log")))
        data = (Path(d) / "events.log").read_bytes()
    return dict(result, log=spec["log"]), data


class RayRunner:
    """Matches as Ray tasks (1 CPU each) on the cluster at ``address``."""

    def __init__(self, address: str = "auto", **init: Any) -> None:
        import ray

        self.ray = ray
        self._joined = not ray.is_initialized()  # Ray started by the caller stays up after close()
        if self._joined:
            if address == "local":
                ray.init(include_dashboard=False, log_to_driver=False, **init)
            else:
                ray.init(address=address, log_to_driver=False, **init)
        self._remote = ray.remote(num_cpus=1, max_retries=RAY_RETRIES,
                                  retry_exceptions=False)(play_match_returning_log)

    @property
    def slots(self) -> int:
        """The cluster's CPUs (matches that run at once)."""
        return int(self.ray.cluster_resources().get("CPU", 1))

    def run(self, specs: list[dict[str, Any]], on_result: OnResult, on_error: OnError) -> None:
        """Play every spec on the cluster; report each as it ends."""
        ray = self.ray
        refs = {self._remote.remote(s): s for s in specs}
        try:
            self._collect(refs, on_result, on_error)
        except KeyboardInterrupt:
            for ref in refs:
                try:
                    ray.cancel(ref, force=True)
                except Exception:
                    pass
            raise Stopped(min(len(refs), self.slots), max(0, len(refs) - self.slots)) from None

    def _collect(self, refs: dict[Any, dict[str, Any]], on_result: OnResult, on_error: OnError) -> None:
        ray = self.ray
        while refs:
            ready, _ = ray.wait(list(refs), num_returns=1)
            for ref in ready:
                spec = refs.pop(ref)
                try:
                    result, log = ray.get(ref)
                    if log is not None:
                        path = Path(spec["log"])
                        write_private(private_dir(path.parent) / path.name, log)
                except Exception as e:
                    on_error(spec, f"{type(e).__name__}: {e}")
                    continue
                on_result(spec, result)

    def close(self) -> None:
        """Leave the cluster (it keeps running), unless the caller had joined it before."""
        if self._joined:
            self.ray.shutdown()


__all__ = ["LOCAL_RETRIES", "LocalRunner", "RAY_RETRIES", "RayRunner", "Stopped", "play_match_returning_log"]
