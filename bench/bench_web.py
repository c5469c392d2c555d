"""Web gateway figures (issue 16): drawing rate in headless Chromium, fan-out latency, seek time.

    .venv/bin/python bench/bench_web.py                       # everything (about 2 minutes)
    .venv/bin/python bench/bench_web.py --robots 1000 --browsers 200 --seconds 15
    .venv/bin/python bench/bench_web.py --only seek

What runs (real processes, TCP on loopback):

1. **Drawing** — a core (4 teams, practice mode, the 512×512 ``big_rooms`` scenario) and 4 ``robo-comp robots`` hosts with
   ``--robots`` robots in all, every robot driving a long ``followPath``; ``robo-comp web
   --core``; Debian's chromium (Playwright, headless, 1280×800) on the page. The page counts
   its ``requestAnimationFrame`` frames and times each draw; reported: frames per second over
   ``--seconds`` (frames that drew; an idle page draws nothing, but robots glide between
   position batches so a moving match draws every frame), draw time p50/p99, the longest gap between two frames, robots on the page
   and the events it applied per second (the core sends 10 position batches per team per second).
   Measured twice in one run: with trails off and no story (the baseline), then with trails on
   and the referee feeding the ticker (a broadcast twice a second, a penalty every two seconds),
   then the same with the debug drawing of ``--debug-robots`` robots at the documented per-tick
   bound (16 shapes a robot, a new frame every 0.5 s, made in the page: :data:`DEBUG_FEED`).
2. **Fan-out** — the same match; this process reads the core's PUB feed directly on a SUB
   socket (the baseline) while a child process holds ``--browsers`` WebSocket clients on the
   gateway's public view. For the first position event of every WebSocket message, the added
   latency is the client's receive time minus the SUB's receive time of the same event
   (``time.monotonic``, one clock for all processes). Reported: p50/p99/max over all clients
   and messages; and the core's CPU (``/proc``) over ``--seconds`` before the gateway started
   and again with the gateway and every client attached.
3. **Seek** — a synthetic 30-minute event log of ``--robots`` robots in the core's format
   (``core.started`` with the demo room, positions once per second per robot as a core logs
   them, finds, losses); the time to build the public view (read once, keyframes), then
   :meth:`RecordingView.seek_text` at 300 random times (p50/p99/max), and in chromium the
   round trip from sending ``seek`` to the state applied and drawn, at 20 random times.

Exit status 1 if a target is missed: ≥ 30 fps (with trails and the ticker), added p99 < 50 ms,
seek < 200 ms. ``--skip-fanout`` measures only the drawing of the live part.
"""
from __future__ import annotations

import argparse
import asyncio
import json
import multiprocessing as mp
import os
import random
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
os.environ.setdefault("PYTHONPATH", str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
import zmq  # noqa: E402

from robo_comp.client import Client, pub_url  # noqa: E402
from robo_comp import protocol as P  # noqa: E402
from robo_comp.core.eventlog import EventLog  # noqa: E402
from robo_comp.launch import start_core, start_robots, stop_all  # noqa: E402
from robo_comp.world.scenario import bundled_scenario_path  # noqa: E402

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]
TEAMS = ["a", "b", "c", "d"]
#: The live match's arena: 512×512 cells of rooms, room for 1,000 robots to drive.
SCENARIO = "big_rooms"


def pct(values: list[float], q: float) -> float:
    """The q-th percentile (0..100) of values."""
    if not values:
        return float("nan")
    return float(np.percentile(np.asarray(values), q))


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a process (from /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def start_web(*args: str) -> tuple[subprocess.Popen[str], str]:
    """``robo-comp web`` on a free port; the process and its URL."""
    proc = subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "web", "--port", "0", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    line = proc.stdout.readline() if proc.stdout else ""
    m = re.search(r"http://\S+", line)
    if m is None:
        proc.kill()
        raise SystemExit(f"robo-comp web did not start: {line}{proc.communicate()[0][-2000:]}")
    threading.Thread(target=lambda: proc.stdout and proc.stdout.read(), daemon=True).start()
    return proc, m.group(0)


def browser():
    """(playwright, browser) on Debian's chromium."""
    from playwright.sync_api import sync_playwright

    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        raise SystemExit("no chromium: apt-get install chromium")
    pw = sync_playwright().start()
    return pw, pw.chromium.launch(executable_path=exe, args=CHROMIUM_ARGS)


# ---------------------------------------------------------------------- the live match
def free_cells(c: Client) -> list[tuple[int, int]]:
    from robo_comp.protocol import unpack_walls

    walls = unpack_walls(c.arena())
    ys, xs = np.nonzero(~walls)
    return list(zip(xs.tolist(), ys.tolist()))


def start_live(state: Path, robots: int) -> tuple[Any, list[Any], Client]:
    # --robots: the scenario gives each team 50; since issue 25 the core refuses robots beyond that
    core = start_core(state, "--teams", ",".join(TEAMS), "--practice", "--scenario", str(bundled_scenario_path(SCENARIO)),
                      "--robots", str(robots // len(TEAMS)))
    hosts = [start_robots(state, t, robots // len(TEAMS)) for t in TEAMS]
    ref = Client(str(state), (state / "referee.token").read_text().strip(), timeout=10)
    t_end = time.monotonic() + 120
    while len([r for r in ref.robots() if r["status"] == "connected"]) < robots:
        if time.monotonic() > t_end:
            raise SystemExit("the robots did not all register within 120 s")
        time.sleep(0.5)
    cells = np.array(free_cells(ref))
    rng = np.random.default_rng(16)
    for r in ref.robots():  # every robot drives a long path near where it is, for the whole bench
        x, y = r["x"], r["y"]
        pts = []
        for _ in range(12):
            near = cells[(np.abs(cells[:, 0] - x) <= 8) & (np.abs(cells[:, 1] - y) <= 8)]
            x, y = (int(v) for v in near[rng.integers(len(near))])
            pts.append([x, y])
        ref.give(r["tag"], "followPath", [pts])
    return core, hosts, ref


def story_feed(state: Path, stop: threading.Event) -> None:
    """The referee's story while the page is measured: a broadcast twice a second and a penalty
    (a score change: the chart and the ticker) every two seconds, so the ticker keeps scrolling."""
    ref = Client(str(state), (state / "referee.token").read_text().strip(), client="bench-story", timeout=10)
    i = 0
    try:
        while not stop.wait(0.5):
            i += 1
            ref.request("broadcast", message=f"bench line {i}")
            if i % 4 == 0:
                ref.request("penalty", team=TEAMS[i // 4 % len(TEAMS)], points=1, reason=f"bench penalty {i // 4}")
    finally:
        ref.close()


#: Debug drawing of ``n`` robots at the documented bound, made in the page: every TICK (0.5 s) each
#: of the first ``n`` robots gets a new frame of MAX_SHAPES shapes around where it is (6 lines,
#: 6 dots, 4 texts), as a team view applies ``debug.draw`` events (the public view never gets them).
DEBUG_FEED = """(n) => {
  const feed = () => {
    const m = robo.model, tags = [...m.robots.keys()].slice(0, n), cols = ["#ff3b30", "#64d2ff", "#ffd60a"];
    for (const tag of tags) {
      const r = m.robots.get(tag), f = [], k = Math.floor(performance.now() / 500) % 10;
      for (let i = 0; i < 6; i++) f.push(["l", r.x, r.y, r.x + 3 * Math.cos(i + k), r.y + 3 * Math.sin(i + k), cols[i % 3]]);
      for (let i = 0; i < 6; i++) f.push(["d", r.x + i - 3, r.y + 2, cols[i % 3]]);
      for (let i = 0; i < 4; i++) f.push(["t", r.x + 1, r.y - 1 - i, `goal ${k}:${i}`, "#ffffff"]);
      m.debug.set(tag, f);
    }
    m.version++;
  };
  feed();
  window.__debugFeed = setInterval(feed, 500);
}"""


def measure_draw(url: str, seconds: float, state: Path | None = None, story: bool = True,
                 debug: int = 0) -> dict[str, Any]:
    """Frames drawn per second; ``story``: with trails on and the ticker fed (``state``: the core's
    folder, for the referee's token), else trails off and no story (the baseline); ``debug``: the
    debug drawing of that many robots at the per-tick bound (:data:`DEBUG_FEED`)."""
    pw, b = browser()
    stop = threading.Event()
    feeder = None
    try:
        page = b.new_page(viewport={"width": 1280, "height": 800})
        page.goto(url)
        page.wait_for_function("() => window.robo && robo.model.robots.size > 0", timeout=30000)
        page.evaluate("(on) => { robo.renderer.trails = on; }", story)
        if story and state is not None:
            feeder = threading.Thread(target=story_feed, args=(state, stop), daemon=True)
            feeder.start()
        if debug:
            page.evaluate(DEBUG_FEED, debug)
        time.sleep(2.0)  # let the first state settle
        s0 = page.evaluate("() => ({f: robo.S.stats.frames, d: robo.S.stats.drawn, e: robo.S.stats.evs, "
                           "t: performance.now()})")
        page.evaluate("() => { robo.S.stats.gaps = []; robo.S.stats.draws = []; }")
        time.sleep(seconds)
        s1 = page.evaluate("() => ({f: robo.S.stats.frames, d: robo.S.stats.drawn, e: robo.S.stats.evs, "
                           "t: performance.now(), "
                           "gaps: robo.S.stats.gaps, draws: robo.S.stats.draws, robots: robo.model.robots.size})")
        lines = page.evaluate("() => document.querySelectorAll('#ticker li').length")
        shapes = page.evaluate("() => robo.renderer.debugShown || 0")
        trails = page.evaluate("() => [...robo.model.robots.values()].filter(r => r.trail.length >= 4).length")
        page.screenshot(path=str(Path(tempfile.gettempdir()) / f"bench_web_draw{'_story' if story else ''}"
                                 f"{'_debug' if debug else ''}.png"))
        dt = (s1["t"] - s0["t"]) / 1000
        return {"fps": (s1["d"] - s0["d"]) / dt, "animation_frames_per_s": (s1["f"] - s0["f"]) / dt, "draw_ms_p50": pct(s1["draws"], 50), "draw_ms_p99": pct(s1["draws"], 99),
                "longest_gap_ms": max(s1["gaps"]) * 1000 if s1["gaps"] else float("nan"),
                "robots": s1["robots"], "events_per_s": (s1["e"] - s0["e"]) / dt,
                "story": story, "ticker_lines": lines, "robots_with_trails": trails,
                "debug_robots": debug, "debug_shapes_drawn": shapes}
    finally:
        stop.set()
        if feeder is not None:
            feeder.join(5)
        b.close()
        pw.stop()


def sub_times(router: str, pub_port: int, seconds: float, out: dict[str, float]) -> None:
    """The baseline: the core's PUB feed read directly; first receive time per position event."""
    sub = zmq.Context.instance().socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"robot.positions")
    sub.connect(pub_url(router, pub_port))
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end:
        if not sub.poll(100):
            continue
        topic, payload = sub.recv_multipart()
        t = time.monotonic()
        d = P.unpack(payload)
        if d.get("tags"):
            key = (f'{d.get("team")}|{d["tags"][0]}|{json.dumps(round(float(d["x"][0]), 2))}|'
                   f'{json.dumps(round(float(d["x"][-1]), 2))}')
            out[key] = -1.0 if key in out else t  # a key seen twice is ambiguous: left out
    sub.close(0)


_KEY = re.compile(r'\["robot\.positions",\{"team":"(\w+)","tags":\[(\d+)')


def clients_role(ws_url: str, n: int, seconds: float, conn: Any) -> None:
    """A child process: ``n`` WebSocket clients on the public view; sends back (key, time) samples."""
    import websockets

    samples: list[tuple[str, float]] = []
    joined = [0]
    seen: list[set[str]] = [set() for _ in range(n)]

    async def one(i: int) -> None:
        async with websockets.connect(ws_url, max_size=None, compression=None) as ws:
            await ws.recv()  # hello
            await ws.send('{"op":"join"}')
            joined[0] += 1
            t_end = time.monotonic() + seconds
            while True:
                left = t_end - time.monotonic()
                if left <= 0:
                    return
                try:
                    text = await asyncio.wait_for(ws.recv(), left)
                except asyncio.TimeoutError:
                    return
                t = time.monotonic()
                m = _KEY.search(text, 0, 200)
                if m:
                    j = text.find('"x":[', m.end())
                    k2 = text.find("]", j + 5)
                    k = text.find(",", j + 5, k2)
                    x0 = text[j + 5:k if k > 0 else k2]
                    xn = text[text.rfind(",", j + 5, k2) + 1 if k > 0 else j + 5:k2]
                    key = f"{m.group(1)}|{m.group(2)}|{x0}|{xn}"
                    if key not in seen[i]:  # a pose batch that repeats (robots standing) counts once
                        seen[i].add(key)
                        samples.append((key, t))

    async def main() -> None:
        await asyncio.gather(*(one(i) for i in range(n)))

    asyncio.run(main())
    conn.send((joined[0], samples))
    conn.close()


def measure_fanout(ref: Client, core_pid: int, url: str, browsers: int, seconds: float) -> dict[str, Any]:
    router, pub_port = ref.url, int(ref.info["pub_port"])
    parent, child = mp.Pipe()
    proc = mp.get_context("spawn").Process(target=clients_role, args=(url.replace("http", "ws") + "ws", browsers,
                                                                      seconds + 6, child))
    proc.start()
    time.sleep(5.0)  # every client joined and took its state
    sub: dict[str, float] = {}
    c0 = cpu_seconds(core_pid)
    t0 = time.monotonic()
    sub_times(router, pub_port, seconds, sub)
    core_cpu = (cpu_seconds(core_pid) - c0) / (time.monotonic() - t0)
    joined, samples = parent.recv()
    proc.join(30)
    added = [(t - sub[k]) * 1000 for k, t in samples if sub.get(k, -1.0) >= 0]
    return {"browsers": joined, "samples": len(added), "unmatched": len(samples) - len(added),
            "added_ms_p50": pct(added, 50), "added_ms_p99": pct(added, 99), "added_ms_max": max(added, default=float("nan")),
            "core_cpu_with_gateway": core_cpu}


# ---------------------------------------------------------------------- seek
def write_long_log(path: Path, robots: int, minutes: float) -> None:
    from robo_comp.world.public import arena_payload
    from robo_comp.world.scenario import bundled_scenario_path, load_scenario

    sc = load_scenario(bundled_scenario_path("demo_room"))
    h, w = sc.walls.shape
    log = EventLog(path)
    t0 = 1_700_000_000.0
    log.append("core.started", None, {"router": "tcp://x", "teams": TEAMS, "arena": arena_payload(sc, TEAMS)}, t=t0)
    rng = np.random.default_rng(16)
    tags = list(range(101, 101 + robots))
    for i, tag in enumerate(tags):
        log.append("robot.registered", TEAMS[i % 4], {"tag": tag, "team": TEAMS[i % 4], "robot_id": f"r{i}",
                                                     "x": 1, "y": 1, "heading": 0}, t=t0 + 0.1)
    x = rng.uniform(1, w - 2, robots)
    y = rng.uniform(1, h - 2, robots)
    for s in range(1, int(minutes * 60) + 1):
        x = np.clip(x + rng.uniform(-0.5, 0.5, robots), 1, w - 2)
        y = np.clip(y + rng.uniform(-0.5, 0.5, robots), 1, h - 2)
        log.append("robot.positions", None, {"tags": tags, "x": np.round(x, 3).tolist(), "y": np.round(y, 3).tolist(),
                                             "heading": rng.uniform(0, 360, robots).round(1).tolist(),
                                             "moving": [True] * robots}, t=t0 + s)
        if s % 60 == 0:
            tag = int(rng.choice(tags))
            log.append("find.reported", TEAMS[(tag - 101) % 4], {"id": s // 60, "team": TEAMS[(tag - 101) % 4], "tag": tag,
                                                               "x": 3, "y": 3, "kind": "victim", "state": "confirmed",
                                                               "evidence": [1], "message": "ok"}, t=t0 + s + 0.5)
            log.append("robot.lost", TEAMS[(tag - 101) % 4], {"tag": tag, "x": 3, "y": 3}, t=t0 + s + 0.6)
    log.close()


def measure_seek(robots: int, minutes: float, browser_seeks: int) -> dict[str, Any]:
    from robo_comp.web.replay import Recording

    tmp = Path(tempfile.mkdtemp(prefix="bench_web_"))
    try:
        log = tmp / "events.log"
        write_long_log(log, robots, minutes)
        t = time.perf_counter()
        rec = Recording(log)
        view = rec.build("public")
        build = time.perf_counter() - t
        rng = random.Random(7)
        took = []
        sizes = []
        for _ in range(300):
            at = rng.uniform(0, rec.duration)
            t = time.perf_counter()
            text = view.seek_text(at, rec.duration)
            took.append((time.perf_counter() - t) * 1000)
            sizes.append(len(text))
        out = {"log_mib": log.stat().st_size / 2**20, "duration_s": rec.duration, "keyframes": len(view.key_times),
               "build_s": build, "server_seek_ms_p50": pct(took, 50), "server_seek_ms_p99": pct(took, 99),
               "server_seek_ms_max": max(took), "state_kib_p50": pct(sizes, 50) / 1024}
        print("seek (server):", json.dumps(out), flush=True)
        web, url = start_web("--replay", str(log))
        pw, b = browser()
        try:
            page = b.new_page(viewport={"width": 1280, "height": 800})
            page.goto(url + "#t=1")
            page.wait_for_function("() => window.robo && robo.model.robots.size > 0", timeout=120000)
            rts = []
            for _ in range(browser_seeks):
                at = round(rng.uniform(0, rec.duration), 3)
                ms = page.evaluate("""(at) => new Promise(ok => {
                  const n = robo.S.stats.states, t0 = performance.now();
                  robo.S.ws.send(JSON.stringify({op: 'seek', t: at}));
                  const check = () => {
                    if (robo.S.stats.states > n) requestAnimationFrame(() => ok(performance.now() - t0));
                    else setTimeout(check, 1);
                  };
                  check();
                })""", at)
                got = page.evaluate("() => robo.S.replay.t")
                assert abs(got - at) < 0.01, (got, at)
                rts.append(ms)
            out.update({"browser_seek_ms_p50": pct(rts, 50), "browser_seek_ms_p99": pct(rts, 99),
                        "browser_seek_ms_max": max(rts)})
        finally:
            b.close()
            pw.stop()
            web.terminate()
            web.wait(10)
        return out
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robots", type=int, default=1000)
    ap.add_argument("--browsers", type=int, default=200)
    ap.add_argument("--seconds", type=float, default=15.0)
    ap.add_argument("--minutes", type=float, default=30.0, help="length of the synthetic log for the seek figure")
    ap.add_argument("--only", choices=["live", "seek"])
    ap.add_argument("--debug-robots", type=int, default=100,
                    help="robots with debug drawing at the per-tick bound in the third drawing run (0: no such run)")
    ap.add_argument("--skip-fanout", action="store_true", help="only the drawing figures of the live part")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    res: dict[str, Any] = {}
    ok = True
    if args.only in (None, "live"):
        tmp = Path(tempfile.mkdtemp(prefix="bench_web_live_"))
        core, hosts, ref = start_live(tmp / "state", args.robots)
        web = None
        try:
            c0, t0 = cpu_seconds(core.pid), time.monotonic()
            time.sleep(args.seconds)
            res["core_cpu_without_gateway"] = (cpu_seconds(core.pid) - c0) / (time.monotonic() - t0)
            web, url = start_web("--core", str(tmp / "state"))
            res["draw_baseline"] = measure_draw(url, args.seconds, story=False)
            print("draw, trails off, no story (baseline):", json.dumps(res["draw_baseline"], indent=1), flush=True)
            res["draw"] = measure_draw(url, args.seconds, tmp / "state", story=True)
            print("draw, trails on, ticker fed:", json.dumps(res["draw"], indent=1), flush=True)
            ok &= res["draw"]["fps"] >= 30
            if args.debug_robots:
                res["draw_debug"] = measure_draw(url, args.seconds, tmp / "state", story=True, debug=args.debug_robots)
                print(f"draw, trails on, ticker fed, debug drawing of {args.debug_robots} robots:",
                      json.dumps(res["draw_debug"], indent=1), flush=True)
                ok &= res["draw_debug"]["fps"] >= 30
            if not args.skip_fanout:
                res["fanout"] = measure_fanout(ref, core.pid, url, args.browsers, args.seconds)
                res["fanout"]["core_cpu_without_gateway"] = res["core_cpu_without_gateway"]
                print("fanout:", json.dumps(res["fanout"], indent=1), flush=True)
                ok &= res["fanout"]["added_ms_p99"] < 50
        finally:
            ref.close()
            if web is not None:
                web.terminate()
                web.wait(10)
            stop_all([core, *hosts])
            shutil.rmtree(tmp, ignore_errors=True)
    if args.only in (None, "seek"):
        res["seek"] = measure_seek(args.robots, args.minutes, 20)
        print("seek:", json.dumps(res["seek"], indent=1), flush=True)
        ok &= res["seek"]["server_seek_ms_max"] < 200 and res["seek"]["browser_seek_ms_p99"] < 200
    if args.json:
        args.json.write_text(json.dumps(res, indent=1))
    print("targets met" if ok else "a target was missed")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
