"""Load and soak (issue 9, part 3): 1,000 robots of 4 teams, team consoles, two walls.

    .venv/bin/python bench/bench_soak.py                 # 10 minutes (the default)
    .venv/bin/python bench/bench_soak.py --minutes 4     # shorter
    .venv/bin/python bench/bench_soak.py --minutes 1 --robots 100 --json out.json

What runs (real processes, TCP on loopback):

* the core: ``robo-comp core --teams a,b,c,d`` (practice mode: the match is always running);
* one ``robo-comp robots`` process per team (``--robots`` / 4 robots each, 250 by default);
* one *walls* process (this script, ``--walls-role``) with two SUB consumers of the PUB feed:
  a fast one that reads everything, and a slow one that sleeps between reads and is only
  attached for the second half of the measured time;
* one *echo* process (``--echo-role``): a bare ROUTER that sends every frame back. A thread
  of this process sends it a frame every 50 ms and times the round trip: the same-run
  baseline, what two processes of this machine need for a round trip under this load with
  no robo_comp code in between;
* in this process: four team consoles (threads, one :class:`Client` each, watching their
  team's events) giving ``goTo`` tasks now or queued and stopping robots, timing every
  round trip; a referee client sampling ``stats`` and the core's RSS.

Timeline: warm-up (20 % of the run, at most 60 s) → phase ``fast-wall-only`` → phase
``slow-wall-attached``. Reported: message rates from ``stats`` (received, events, dropped),
p50/p99 give/stop latency per phase, core RSS over time and its growth after warm-up, and
the acknowledged-give check: every acknowledged give must be in the core's event log as
``task.given`` and, at the end, either finished (``task.done``, done or cancelled, in the log)
or still the robot's current, pending or queued task; and it must have been pushed as a
``task.given`` event to the watching console.
"""
from __future__ import annotations

import argparse
import json
import os
import random
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import zmq

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from robo_comp.client import Client, pub_url  # noqa: E402
from robo_comp import protocol as P  # noqa: E402
from robo_comp.protocol.logfile import read_log  # noqa: E402
from robo_comp.errors import RoboCompError  # noqa: E402
from robo_comp.launch import start_core, start_robots, stop_all  # noqa: E402

TEAMS = ("a", "b", "c", "d")
SLOW_WALL_SLEEP = 0.05  # seconds the slow wall sleeps between two reads (≤ 20 events/s)


# ---------------------------------------------------------------------------- helpers
def rss_kib(pid: int) -> int:
    """Resident set size of process ``pid`` in KiB (``VmRSS`` of /proc/PID/status)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def cpu_seconds(pid: int) -> float:
    """User + system CPU time process ``pid`` used so far (``/proc/PID/stat``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def percentile(values: list[float], q: float) -> float:
    """The ``q`` percentile (0–100) of ``values`` (nan when empty)."""
    if not values:
        return float("nan")
    return float(np.percentile(np.asarray(values), q))


def free_cells(arena: dict[str, Any]) -> list[tuple[int, int]]:
    """Every free cell of an arena payload."""
    walls = P.unpack_walls(arena)
    ys, xs = np.nonzero(~walls)
    return list(zip(xs.tolist(), ys.tolist()))


# ---------------------------------------------------------------------------- walls process
def walls_role(router: str, pub_port: int, seconds: float, slow_after: float, out: Path) -> None:
    """Run the two wall consumers for ``seconds``; write their counts to ``out`` as JSON."""
    ctx = zmq.Context.instance()
    url = pub_url(router, pub_port)
    stop_at = time.monotonic() + seconds
    results: dict[str, Any] = {}

    def consume(name: str, delay: float, start_after: float) -> None:
        time.sleep(start_after)
        sub = ctx.socket(zmq.SUB)
        sub.setsockopt(zmq.LINGER, 0)
        sub.setsockopt(zmq.SUBSCRIBE, b"")
        sub.connect(url)
        n = 0
        topics: dict[str, int] = {}
        t0 = time.monotonic()
        while time.monotonic() < stop_at:
            if not sub.poll(200):
                continue
            topic, payload = sub.recv_multipart()
            P.unpack(payload)
            n += 1
            key = topic.decode()
            topics[key] = topics.get(key, 0) + 1
            if delay:
                time.sleep(delay)
        sub.close(0)
        elapsed = time.monotonic() - t0
        results[name] = {"events": n, "seconds": round(elapsed, 1), "rate": round(n / max(elapsed, 1e-9), 1),
                         "topics": topics}

    threads = [threading.Thread(target=consume, args=("fast", 0.0, 0.0)),
               threading.Thread(target=consume, args=("slow", SLOW_WALL_SLEEP, slow_after))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    out.write_text(json.dumps(results))


# ---------------------------------------------------------------------------- echo baseline
def echo_role(port_file: Path) -> None:
    """A bare ROUTER echo server (the baseline): runs until killed."""
    sock = zmq.Context.instance().socket(zmq.ROUTER)
    port = sock.bind_to_random_port("tcp://127.0.0.1")
    port_file.write_text(str(port))
    while True:
        sock.send_multipart(sock.recv_multipart())


def echo_probe(url: str, phase_of: Any, stop_at: float, out: dict[str, list[float]], every: float = 0.05) -> None:
    """Time a round trip to the echo server every ``every`` seconds until ``stop_at``."""
    sock = zmq.Context.instance().socket(zmq.DEALER)
    sock.setsockopt(zmq.LINGER, 0)
    sock.connect(url)
    payload = P.request("robots", 1, {})
    nxt = time.monotonic()
    while time.monotonic() < stop_at:
        t0 = time.perf_counter()
        sock.send(payload)
        if sock.poll(5000):
            sock.recv()
            out.setdefault(phase_of(), []).append((time.perf_counter() - t0) * 1000)
        nxt += every
        time.sleep(max(0.0, nxt - time.monotonic()))
    sock.close(0)


# ---------------------------------------------------------------------------- consoles
@dataclass
class Console:
    """One team console: gives tasks, stops robots, watches its team's events."""

    team: str
    client: Client
    tags: list[int]
    cells: list[tuple[int, int]]
    rate: float
    rng: random.Random
    latency: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    acked: dict[int, int] = field(default_factory=dict)  # acknowledged task id -> tag
    given_events: set[int] = field(default_factory=set)
    errors: dict[str, int] = field(default_factory=dict)

    def _drain_events(self) -> None:
        ev = self.client.events
        while ev:
            e = ev.popleft()
            if e.get("topic") == "task.given":
                self.given_events.add(e["data"]["task_id"])

    def _timed(self, phase: str, kind: str, fn: Any, *args: Any, **kw: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return fn(*args, **kw)
        except RoboCompError as e:
            self.errors[e.code] = self.errors.get(e.code, 0) + 1
            return None
        finally:
            self.latency.setdefault(phase, {}).setdefault(kind, []).append((time.perf_counter() - t0) * 1000)
            self._drain_events()

    def waiting(self) -> set[int]:
        """Ids of the tasks the team's robots still run or wait to run (asked at the end)."""
        ids: set[int] = set()
        for tag in set(self.acked.values()):
            t = self.client.tasks(tag)
            ids |= {x["task_id"] for x in [t["current"], t["pending"], *t["queued"]] if x}
        return ids

    def one_command(self, phase: str) -> None:
        """Give now (70 %), give queued (15 %) or stop (15 %) a random robot of the team."""
        tag = self.rng.choice(self.tags)
        op = self.rng.random()
        if op < 0.85:
            x, y = self.rng.choice(self.cells)
            rep = self._timed(phase, "give", self.client.give, tag, "goTo", [x, y], queue=op >= 0.70)
            if rep is not None:
                self.acked[rep["task_id"]] = tag
        else:
            self._timed(phase, "stop", self.client.stop, tag)

    def run(self, phase_of: Any, stop_at: float) -> None:
        """Issue commands at ``rate`` per second until ``stop_at`` (monotonic)."""
        period = 1.0 / self.rate
        nxt = time.monotonic()
        while time.monotonic() < stop_at:
            self.one_command(phase_of())
            nxt += period
            time.sleep(max(0.0, nxt - time.monotonic()))
        t_end = time.monotonic() + 2.0  # late task.given pushes
        while time.monotonic() < t_end and self.client.next_event(0.2) is not None:
            self._drain_events()


# ---------------------------------------------------------------------------- the run
def wait_file(path: Path, timeout: float) -> None:
    """Wait until ``path`` exists and is not empty."""
    end = time.monotonic() + timeout
    while not (path.exists() and path.read_text()):
        if time.monotonic() > end:
            raise SystemExit(f"{path} did not appear within {timeout:.0f} s")
        time.sleep(0.05)


def wait_registered(ref: Client, n: int, timeout: float) -> float:
    """Wait until the referee sees ``n`` connected robots; return the seconds it took."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        st = ref.request("stats")
        if st["robots"].get("connected", 0) >= n:
            return time.monotonic() - t0
        time.sleep(0.5)
    raise SystemExit(f"only {ref.request('stats')['robots']} robots after {timeout:.0f} s")


def summarize_latency(consoles: list[Console], echo: dict[str, list[float]]) -> dict[str, dict[str, dict[str, float]]]:
    """p50/p99/max and counts of give and stop round trips per phase, and of the echo baseline."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for phase in ("fast-wall-only", "slow-wall-attached"):
        for kind in ("give", "stop", "echo"):
            v = echo.get(phase, []) if kind == "echo" else [
                x for c in consoles for x in c.latency.get(phase, {}).get(kind, [])]
            out.setdefault(phase, {})[kind] = {"n": len(v), "p50_ms": round(percentile(v, 50), 2),
                                               "p99_ms": round(percentile(v, 99), 2),
                                               "max_ms": round(max(v), 2) if v else float("nan")}
    return out


def run(args: argparse.Namespace) -> dict[str, Any]:
    """The whole soak; returns the figures."""
    total = args.minutes * 60.0
    warm = min(60.0, 0.2 * total)
    half = (total - warm) / 2
    state = Path(tempfile.mkdtemp(prefix="rc-soak-"))
    procs: list[subprocess.Popen[bytes]] = []
    core = start_core(state, "--teams", ",".join(TEAMS), "--heartbeat", str(args.heartbeat))
    procs.append(core)
    try:
        per = args.robots // len(TEAMS)
        for team in TEAMS:
            procs.append(start_robots(state, team, per, "--report-hz", str(args.report_hz)))
        ref = Client(str(state), (state / "referee.token").read_text().strip(), client="soak-referee",
                     timeout=10.0)
        reg_s = wait_registered(ref, per * len(TEAMS), 180.0)
        print(f"{per * len(TEAMS)} robots registered in {reg_s:.1f} s", flush=True)
        walls_out = state / "walls.json"
        walls_proc = subprocess.Popen(
            [sys.executable, __file__, "--walls-role", ref.url, str(ref.info["pub_port"]), str(total),
             str(warm + half), str(walls_out)], stdin=subprocess.DEVNULL)
        procs.append(walls_proc)
        t0 = time.monotonic()
        stop_at = t0 + total

        def phase_of() -> str:
            e = time.monotonic() - t0
            return "warm-up" if e < warm else ("fast-wall-only" if e < warm + half else "slow-wall-attached")

        consoles = []
        for i, team in enumerate(TEAMS):
            c = Client(str(state), (state / "teams" / f"{team}.token").read_text().strip(),
                       client=f"console-{team}", timeout=10.0)
            c.watch()
            tags = [r["tag"] for r in c.robots()]
            consoles.append(Console(team, c, tags, free_cells(c.arena()), args.rate, random.Random(i)))
        threads = [threading.Thread(target=c.run, args=(phase_of, stop_at), daemon=True) for c in consoles]
        echo_port = state / "echo.port"
        echo_proc = subprocess.Popen([sys.executable, __file__, "--echo-role", str(echo_port)],
                                     stdin=subprocess.DEVNULL)
        procs.append(echo_proc)
        wait_file(echo_port, 20.0)
        echo: dict[str, list[float]] = {}
        threads.append(threading.Thread(target=echo_probe, daemon=True, args=(
            f"tcp://127.0.0.1:{echo_port.read_text()}", phase_of, stop_at, echo)))
        for t in threads:
            t.start()
        pids = {"core": core.pid, **{f"robots-{t}": p.pid for t, p in zip(TEAMS, procs[1:1 + len(TEAMS)])},
                "walls": walls_proc.pid, "echo": echo_proc.pid, "consoles (this process)": os.getpid()}
        samples = sample_loop(ref, pids, t0, stop_at, args.sample, phase_of)
        for t in threads:
            t.join(timeout=120)
        walls_proc.wait(timeout=60)  # the walls process writes its counts and ends
        walls = json.loads(walls_out.read_text()) if walls_out.exists() else {}
        final = ref.request("stats")
        waiting = set().union(*(c.waiting() for c in consoles))  # first: what finishes later is logged
        check = check_acked(consoles, waiting, state / "events.log")
        for c in consoles:
            c.client.close()
        ref.close()
        return report(args, reg_s, warm, half, samples, consoles, walls, final, check, echo)
    finally:
        stop_all(procs)


def check_acked(consoles: list[Console], waiting: set[int], log_path: Path) -> dict[str, Any]:
    """Every acknowledged give: logged as given, and finished in the log or still waiting."""
    given: set[int] = set()
    finished: set[int] = set()
    for rec in read_log(log_path, strict=False):  # the core is still writing: a partial tail is fine
        if rec.topic == "task.given":
            given.add(rec.data["task_id"])
        elif rec.topic == "task.done":
            finished.add(rec.data["task_id"])
    acked = {i: c.acked[i] for c in consoles for i in c.acked}
    return {"acked_gives": len(acked),
            "not_logged": sorted(i for i in acked if i not in given),
            "lost": sorted(i for i in acked if i not in finished and i not in waiting),
            "finished": sum(1 for i in acked if i in finished),
            "still_waiting": sum(1 for i in acked if i in waiting and i not in finished),
            "not_pushed": sum(1 for c in consoles for i in c.acked if i not in c.given_events)}


def sample_loop(ref: Client, pids: dict[str, int], t0: float, stop_at: float, every: float,
                phase_of: Any) -> list[dict[str, Any]]:
    """Sample ``stats``, the core's RSS and every process's CPU time every ``every`` seconds
    until ``stop_at``."""
    pid = pids["core"]
    samples = []
    while True:
        now = time.monotonic()
        st = ref.request("stats")
        samples.append({"t": round(now - t0, 1), "phase": phase_of(), "rss_kib": rss_kib(pid),
                        "cpu_s": {name: cpu_seconds(p) for name, p in pids.items()},
                        "received": st["received"], "events": st["events"], "dropped": st["dropped"],
                        "errors": st["errors"], "connected": st["robots"].get("connected", 0)})
        s = samples[-1]
        print(f"t={s['t']:6.1f}s {s['phase']:<18} rss={s['rss_kib'] / 1024:6.1f} MiB "
              f"received={s['received']} events={s['events']} dropped={s['dropped']} "
              f"connected={s['connected']}", flush=True)
        if now >= stop_at:
            return samples
        time.sleep(max(0.0, min(every, stop_at - time.monotonic())))


def report(args: argparse.Namespace, reg_s: float, warm: float, half: float, samples: list[dict[str, Any]],
           consoles: list[Console], walls: dict[str, Any], final: dict[str, Any],
           check: dict[str, Any], echo: dict[str, list[float]]) -> dict[str, Any]:
    """Turn the samples into the figures of docs/perf-soak.md."""
    first = next(s for s in samples if s["t"] >= warm)
    last = samples[-1]
    dt = last["t"] - first["t"]
    rates = {k: round((last[k] - first[k]) / dt, 1) for k in ("received", "events", "dropped", "errors")}
    cpu = {name: round(100.0 * (last["cpu_s"][name] - first["cpu_s"][name]) / dt, 1) for name in last["cpu_s"]}
    rss_after = [s["rss_kib"] for s in samples if s["t"] >= warm]
    mid = [s["rss_kib"] for s in samples if s["phase"] == "fast-wall-only"]
    growth = 100.0 * (rss_after[-1] - rss_after[0]) / rss_after[0]
    growth_a = 100.0 * (mid[-1] - mid[0]) / mid[0] if len(mid) > 1 else float("nan")
    errors: dict[str, int] = {}
    for c in consoles:
        for k, v in c.errors.items():
            errors[k] = errors.get(k, 0) + v
    return {
        "command": " ".join(sys.argv), "minutes": args.minutes, "robots": args.robots, "teams": list(TEAMS),
        "report_hz": args.report_hz, "console_rate": args.rate, "warmup_s": warm, "phase_s": half,
        "registration_s": round(reg_s, 1), "rates_per_s": rates, "cpu_pct": cpu, "final_stats": final,
        "rss_mib": {"start_after_warmup": round(rss_after[0] / 1024, 1), "end": round(rss_after[-1] / 1024, 1),
                    "max": round(max(rss_after) / 1024, 1), "growth_pct": round(growth, 2),
                    "growth_pct_fast_only_phase": round(growth_a, 2)},
        "rss_series": [(s["t"], round(s["rss_kib"] / 1024, 1)) for s in samples],
        "latency": summarize_latency(consoles, echo), "command_errors": errors,
        "acked_check": check, "walls": walls,
    }


def main(argv: list[str] | None = None) -> int:
    """Parse options and run the soak (or, internally, the walls process)."""
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "--echo-role":
        echo_role(Path(argv[1]))
        return 0
    if argv and argv[0] == "--walls-role":
        router, port, seconds, slow_after, out = argv[1:6]
        walls_role(router, int(port), float(seconds), float(slow_after), Path(out))
        return 0
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--minutes", type=float, default=10.0, help="length of the run (default 10)")
    p.add_argument("--robots", type=int, default=1000, help="robots in all, split over 4 teams (default 1000)")
    p.add_argument("--report-hz", type=float, default=10.0, help="position reports per second of a moving robot")
    p.add_argument("--rate", type=float, default=5.0, help="commands per second per team console")
    p.add_argument("--heartbeat", type=float, default=1.0, help="the core's heartbeat (s)")
    p.add_argument("--sample", type=float, default=10.0, help="seconds between stats/RSS samples")
    p.add_argument("--json", help="also write the figures to this file")
    args = p.parse_args(argv)
    res = run(args)
    text = json.dumps(res, indent=2)
    print(text)
    if args.json:
        Path(args.json).write_text(text)
    check = res["acked_check"]
    return 1 if check["not_logged"] or check["lost"] or check["not_pushed"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
