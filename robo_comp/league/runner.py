"""Where league matches are played: in this process, on a local process pool, or on Ray.

Every runner takes match specs (plain data, see :func:`robo_comp.league.engine.play_match`)
and calls ``on_result(spec, result)`` or ``on_error(spec, message)`` as matches end, in the
order they end. A match is deterministic, so where it ran does not change its result.

* :class:`LocalRunner` — ``workers`` processes of a :class:`~concurrent.futures.ProcessPoolExecutor`
  (one worker: played in this process, no pool). The workers are started with ``spawn`` (no
  inherited threads or sockets), so a script that uses more than one needs the usual
  ``if __name__ == "__main__":`` guard;
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
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any

from robo_comp.league.engine import play_match
from robo_comp.private_files import private_dir, write_private

OnResult = Callable[[dict[str, Any], dict[str, Any]], None]
OnError = Callable[[dict[str, Any], str], None]
#: How often Ray runs a match again after its worker died.
RAY_RETRIES = 3


class LocalRunner:
    """Matches on ``workers`` local processes (1: in this process)."""

    def __init__(self, workers: int = 1) -> None:
        self.workers = max(1, int(workers))

    @property
    def slots(self) -> int:
        """How many matches run at once."""
        return self.workers

    def run(self, specs: list[dict[str, Any]], on_result: OnResult, on_error: OnError) -> None:
        """Play every spec; report each as it ends."""
        if self.workers == 1:
            for spec in specs:
                try:
                    result = play_match(spec)
                except Exception:
                    on_error(spec, traceback.format_exc(limit=5))
                    continue
                on_result(spec, result)
            return
        ctx = multiprocessing.get_context("spawn")  # a clean interpreter: no inherited threads or sockets
        with ProcessPoolExecutor(self.workers, mp_context=ctx) as pool:
            running: dict[Future[dict[str, Any]], dict[str, Any]] = {pool.submit(play_match, s): s for s in specs}
            while running:
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for fut in done:
                    spec = running.pop(fut)
                    try:
                        result = fut.result()
                    except Exception as e:
                        # the worker's traceback, as the in-process path gives (the pool keeps it as the cause)
                        remote = str(e.__cause__).strip().strip('"').strip() if e.__cause__ is not None else ""
                        on_error(spec, remote or f"{type(e).__name__}: {e}")
                        continue
                    on_result(spec, result)

    def close(self) -> None:
        """Nothing to release."""


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


__all__ = ["LocalRunner", "RAY_RETRIES", "RayRunner", "play_match_returning_log"]
