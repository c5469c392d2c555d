"""Web gateway figures (issues 16 and 31): drawing rate in headless Chromium, fan-out latency
beside a bare WebSocket broadcaster, seek time.

    .venv/bin/python bench/bench_web.py                       # everything (several minutes)
    .venv/bin/python bench/bench_web.py --only fanout --clients 200 1000 --baseline 8820265
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
2. **Fan-out** — the same match. This process reads the core's PUB feed directly on a SUB
   socket (the bare ZeroMQ hop) while two child processes hold ``--clients`` WebSocket clients
   (:class:`RawClient`: the upgrade, frame lengths and pongs, no more) on, in turn: the
   gateway's public view; **the peer**, a bare WebSocket broadcaster of our own on the same
   server stack (Starlette on uvicorn, the gateway's settings) that forwards every PUB frame
   as it came to every client, framed once, without a core session, a model or JSON
   (:func:`peer_app`); **peer-asgi**, the same with one ``await send_bytes`` per client; and,
   with ``--baseline REV``, the gateway of that git revision. For the first position event of
   every WebSocket message, the added latency is the time the kernel stamped on the client's
   socket when the message's last bytes arrived (``SO_TIMESTAMPNS``) minus the SUB's receive
   time of the same event (both ``CLOCK_REALTIME``); also reported, the time the client process
   read it (what a thousand clients in two Python processes on this machine add on top).
   p50/p99/max over all clients and messages, the CPU of the core, the gateway and the peer
   meanwhile, ``uptime``, and how many fresh states the clients got while measured.
3. **Seek** — a synthetic 30-minute event log of ``--robots`` robots in the core's format
   (``core.started`` with the demo room, positions once per second per robot as a core logs
   them, finds, losses); the time to build the public view (read once, keyframes), then
   :meth:`RecordingView.seek_text` at 300 random times (p50/p99/max), and in chromium the
   round trip from sending ``seek`` to the state applied and drawn, at 20 random times.

Exit status 1 if a target is missed: ≥ 30 fps (with trails and the ticker), the gateway's added
p99 < 5 ms at 200 clients and < 10 ms at 1,000 (issue 31), seek < 200 ms. ``--skip-fanout``
measures only the drawing of the live part; ``--only fanout`` only the fan-out.
"""
from __future__ import annotations

import argparse
import asyncio
import base64
import contextlib
import json
import multiprocessing as mp
import os
import random
import re
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
import zlib
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

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
#: Points of every robot's path (up to 8 cells apart): minutes of driving, the whole bench long.
PATH_POINTS = 150


def pct(values: list[float], q: float) -> float:
    """The q-th percentile (0..100) of values."""
    if not values:
        return float("nan")
    return float(np.percentile(np.asarray(values), q))


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a process (from /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def start_web(*args: str, pythonpath: Path | None = None) -> tuple[subprocess.Popen[str], str]:
    """``robo-comp web`` on a free port (of the tree at ``pythonpath``, else this one); the
    process and its URL."""
    env = dict(os.environ, PYTHONPATH=str(pythonpath)) if pythonpath else None
    proc = subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "web", "--port", "0", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                            cwd=pythonpath)  # (``-m`` puts the working folder first on the path)
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
                      "--robots", str(-(-robots // len(TEAMS))))
    hosts = [start_robots(state, t, robots // len(TEAMS)) for t in TEAMS]
    ref = Client(str(state), (state / "referee.token").read_text().strip(), timeout=10)
    t_end = time.monotonic() + 300
    while len([r for r in ref.robots() if r["status"] == "connected"]) < robots:
        if time.monotonic() > t_end:
            ref.close()
            stop_all([core, *hosts])
            raise SystemExit("the robots did not all register within 300 s")
        time.sleep(0.5)
    cells = np.array(free_cells(ref))
    rng = np.random.default_rng(16)
    for r in ref.robots():  # every robot drives a long path near where it is, for the whole bench
        x, y = r["x"], r["y"]
        pts = []
        for _ in range(PATH_POINTS):
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


# ---------------------------------------------------------------------- fan-out
#: Processes holding the WebSocket clients (this machine has 2 cores).
CLIENT_PROCS = 2
_GW_KEY = re.compile(rb'\["robot\.positions",\{"team":"(\w+)","tags":\[(\d+)')


def gateway_key(payload: bytes) -> bytes | None:
    """A gateway message's key: team, first tag, first and last x of its first position event
    (``None`` for messages without one)."""
    m = _GW_KEY.search(payload, 0, 200)
    if m is None:
        return None
    j = payload.find(b'"x":[', m.end()) + 5
    k2 = payload.find(b"]", j)
    k = payload.find(b",", j, k2)
    first = payload[j:k if k > 0 else k2]
    last = payload[payload.rfind(b",", j, k2) + 1 if k > 0 else j:k2]
    return b"|".join((m.group(1), m.group(2), first, last))


def sub_gateway_key(payload: bytes) -> bytes | None:
    """The same key from the core's PUB frame, rounded as the gateway rounds it for the page."""
    from robo_comp.web.hub import compact

    d = P.unpack(payload)
    if not d.get("tags"):
        return None
    x = compact("robot.positions", d)["x"]
    return b"|".join((str(d.get("team")).encode(), str(d["tags"][0]).encode(), json.dumps(x[0]).encode(),
                      json.dumps(x[-1]).encode()))


def peer_key(payload: bytes) -> bytes | None:
    """The peer forwards the PUB frame as it is: its length and CRC are its key."""
    return b"%d|%d" % (len(payload), zlib.crc32(payload))


def sub_times(router: str, pub_port: int, seconds: float, key: Any, out: dict[bytes, float]) -> None:
    """The baseline: the core's PUB feed read directly; receive time per position event, by key
    (every frame waiting is taken and timed before any is decoded, so a burst's later frames are
    not timed late by the decoding of the earlier ones)."""
    sub = zmq.Context.instance().socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"robot.positions")
    sub.connect(pub_url(router, pub_port))
    t_end = time.monotonic() + seconds
    got: list[tuple[bytes, float]] = []
    while time.monotonic() < t_end:
        if not sub.poll(100):
            continue
        while True:
            try:
                _, payload = sub.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                break
            got.append((payload, time.time()))  # the clock of the clients' kernel stamps
        for payload, t in got:
            k = key(payload)
            if k is not None:
                out[k] = -1.0 if k in out else t  # a key seen twice is ambiguous: left out
        got.clear()
    sub.close(0)


#: ``SO_TIMESTAMPNS`` on Linux (the standard library does not name it): the kernel stamps each
#: packet with the time it reached the socket, read back with ``recvmsg``.
SO_TIMESTAMPNS = 35


class RawClient:
    """A WebSocket client reduced to what the measure needs (the HTTP upgrade, frame lengths,
    pongs), on a socket whose packets the kernel stamps when they arrive (``SO_TIMESTAMPNS``).
    A message's time is the kernel's stamp of the data that completed it: what the server adds,
    without the time this process takes to get to the socket (1,000 clients in two Python
    processes would otherwise measure the clients). The time this process read it is kept too."""

    def __init__(self, url: str, key: Any, join: bool) -> None:
        u = urlsplit(url)
        self.addr = (u.hostname, u.port)
        self.request = (f"GET {u.path} HTTP/1.1\r\nHost: {u.netloc}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                        f"Sec-WebSocket-Key: {base64.b64encode(os.urandom(16)).decode()}\r\n"
                        "Sec-WebSocket-Version: 13\r\n\r\n").encode()
        self.key = key
        self.join = join
        self.buf = bytearray()
        self.upgraded = False
        self.ready: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self.recording = False
        self.seen: set[bytes] = set()
        self.samples: list[tuple[bytes, float, float]] = []  # (key, kernel's time, this process's time)
        self.messages = self.states = 0
        self.sock = socket.socket()
        self.sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
        self.sock.setblocking(False)

    async def start(self) -> None:
        """Connect and ask for the upgrade."""
        loop = asyncio.get_running_loop()
        await loop.sock_connect(self.sock, self.addr)
        await loop.sock_sendall(self.sock, self.request)
        loop.add_reader(self.sock.fileno(), self.readable)

    def close(self) -> None:
        """Stop reading and close the socket."""
        asyncio.get_running_loop().remove_reader(self.sock.fileno())
        self.sock.close()

    def send(self, op: int, payload: bytes) -> None:
        """One masked client frame (payloads below 126 bytes)."""
        mask = os.urandom(4)
        assert len(payload) < 126
        with contextlib.suppress(OSError):
            self.sock.send(bytes((0x80 | op, 0x80 | len(payload))) + mask
                           + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))

    def readable(self) -> None:
        try:
            data, anc, _, _ = self.sock.recvmsg(1 << 20, 64)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data, anc = b"", []
        tu = time.time()
        if not data:
            asyncio.get_running_loop().remove_reader(self.sock.fileno())
            if not self.ready.done():
                self.ready.set_exception(RuntimeError("the server closed the connection"))
            return
        tk = tu
        for level, kind, d in anc:
            if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS:
                sec, ns = struct.unpack("qq", d[:16])
                tk = sec + ns * 1e-9
        self.received(data, tk, tu)

    def received(self, data: bytes, tk: float, tu: float) -> None:
        buf = self.buf
        buf += data
        if not self.upgraded:
            i = buf.find(b"\r\n\r\n")
            if i < 0:
                return
            if not buf.startswith(b"HTTP/1.1 101"):
                if not self.ready.done():
                    self.ready.set_exception(RuntimeError(bytes(buf[:200]).decode(errors="replace")))
                return
            del buf[:i + 4]
            self.upgraded = True
            if self.join:
                self.send(1, b'{"op":"join"}')
            elif not self.ready.done():
                self.ready.set_result(None)
        while len(buf) >= 2:
            n = buf[1] & 0x7F
            h = 2
            if n == 126:
                if len(buf) < 4:
                    return
                n, h = int.from_bytes(buf[2:4], "big"), 4
            elif n == 127:
                if len(buf) < 10:
                    return
                n, h = int.from_bytes(buf[2:10], "big"), 10
            if len(buf) < h + n:
                return
            op = buf[0] & 0x0F
            payload = bytes(buf[h:h + n])
            del buf[:h + n]
            if op == 9:
                self.send(10, payload)  # pong: uvicorn closes a client that does not answer its pings
            elif op in (1, 2):
                self.message(payload, tk, tu)

    def message(self, payload: bytes, tk: float, tu: float) -> None:
        self.messages += 1
        if payload.startswith(b'{"type":"state"'):
            self.states += 1
            if not self.ready.done():
                self.ready.set_result(None)
        if self.recording:
            k = self.key(payload)
            if k is not None and k not in self.seen:  # a pose batch that repeats (robots standing) counts once
                self.seen.add(k)
                self.samples.append((k, tk, tu))


def clients_role(url: str, n: int, kind: str, conn: Any) -> None:
    """A child process: ``n`` WebSocket clients on ``url`` (``kind``: ``gateway``, they join the
    public view; ``peer``). Says ``ready`` when every client is in, records between the parent's
    ``go`` and ``stop``, then sends back its samples."""

    async def main() -> None:
        loop = asyncio.get_running_loop()
        key = gateway_key if kind == "gateway" else peer_key
        clients = [RawClient(url, key, kind == "gateway") for _ in range(n)]
        for k in range(0, n, 50):  # in steps: a burst of 1,000 SYNs would overflow the listen backlog
            await asyncio.gather(*(c.start() for c in clients[k:k + 50]))
        await asyncio.wait_for(asyncio.gather(*(c.ready for c in clients)), 300)
        orders: asyncio.Queue[str] = asyncio.Queue()
        loop.add_reader(conn.fileno(), lambda: orders.put_nowait(conn.recv()))
        conn.send(("ready", len(clients)))
        assert await orders.get() == "go"
        m0 = [c.messages for c in clients]
        s0 = sum(c.states for c in clients)
        for c in clients:
            c.recording = True
        assert await orders.get() == "stop"
        for c in clients:
            c.recording = False
        loop.remove_reader(conn.fileno())
        samples = [s for c in clients for s in c.samples]
        got = [c.messages - a for c, a in zip(clients, m0)]
        conn.send((samples, {"messages_min": min(got), "messages_max": max(got),
                             "states": sum(c.states for c in clients) - s0}))
        for c in clients:
            c.close()

    asyncio.run(main())
    conn.close()


#: The peers: how the bare broadcaster sends a PUB frame to its clients.
PEERS = {
    "peer": "frames",  # framed once, the same bytes written to every client's socket (the stack's floor)
    "peer-asgi": "asgi",  # one ``await send_bytes`` after another through ASGI (the plain way)
}


def peer_app(pub: str, send: str) -> Any:
    """The peer: a bare WebSocket broadcaster on the gateway's server stack (Starlette on uvicorn,
    the gateway's settings, :func:`robo_comp.web.wire.config`) that forwards every frame of the
    core's PUB feed, as it came, to every client: no core session, no model, no JSON, no batching,
    nothing held or dropped. ``send``: ``frames``, each PUB frame framed once as a binary
    WebSocket message and those bytes written to every client's socket (the wire the gateway
    uses), or ``asgi``, one ``await websocket.send_bytes`` after another."""
    import zmq.asyncio
    from starlette.applications import Starlette
    from starlette.routing import WebSocketRoute
    from starlette.websockets import WebSocket, WebSocketDisconnect

    from robo_comp.web.wire import frame_text, wire_of

    clients: dict[WebSocket, Any] = {}

    async def ws(websocket: WebSocket) -> None:
        await websocket.accept()
        clients[websocket] = wire_of(websocket.scope)
        try:
            while True:
                await websocket.receive_text()
        except WebSocketDisconnect:
            pass
        finally:
            clients.pop(websocket, None)

    async def relay() -> None:
        sub = zmq.asyncio.Context.instance().socket(zmq.SUB)
        sub.setsockopt(zmq.SUBSCRIBE, b"")
        sub.connect(pub)
        while True:
            _, payload = await sub.recv_multipart()
            if send == "frames":
                data = b"\x82" + frame_text(payload)[1:]  # the same header with the binary opcode
                for wire in list(clients.values()):
                    wire.write(data, "")
                continue
            for c in list(clients):
                try:
                    await c.send_bytes(payload)
                except Exception:  # a client that left
                    clients.pop(c, None)

    @contextlib.asynccontextmanager
    async def lifespan(app: Any) -> Any:
        task = asyncio.get_running_loop().create_task(relay())
        yield
        task.cancel()

    return Starlette(routes=[WebSocketRoute("/ws", ws)], lifespan=lifespan)


def peer_main(pub: str, send: str) -> None:
    """``bench_web.py --peer PUB_URL --peer-send frames|asgi``: serve a peer on a free port and
    print its URL."""
    import uvicorn

    from robo_comp.web.wire import config

    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.bind(("127.0.0.1", 0))
    sock.listen(2048)  # as the gateway
    print(f"peer: serving on http://127.0.0.1:{sock.getsockname()[1]}/", flush=True)
    asyncio.run(uvicorn.Server(config(peer_app(pub, send))).serve(sockets=[sock]))


def start_peer(pub: str, send: str) -> tuple[subprocess.Popen[str], str]:
    """A peer in a process of its own; the process and its URL."""
    proc = subprocess.Popen([sys.executable, __file__, "--peer", pub, "--peer-send", send], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    line = proc.stdout.readline() if proc.stdout else ""
    m = re.search(r"http://\S+", line)
    if m is None:
        proc.kill()
        raise SystemExit(f"the peer did not start: {line}{proc.communicate()[0][-2000:]}")
    threading.Thread(target=lambda: proc.stdout and proc.stdout.read(), daemon=True).start()
    return proc, m.group(0)


def uptime() -> str:
    """The machine's load, as ``uptime`` prints it."""
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def measure_fanout(ref: Client, pids: dict[str, int], url: str, kind: str, clients: int,
                   seconds: float) -> dict[str, Any]:
    """Added latency of ``clients`` WebSocket clients on ``url`` (the gateway's public view or the
    peer) over a SUB on the core's PUB, and the CPU of the processes in ``pids`` meanwhile."""
    router, pub_port = ref.url, int(ref.info["pub_port"])
    ctx = mp.get_context("spawn")
    ws_url = url.replace("http", "ws", 1) + "ws"
    per = [clients // CLIENT_PROCS + (i < clients % CLIENT_PROCS) for i in range(CLIENT_PROCS)]
    pipes, procs = [], []
    for n in per:
        parent, child = ctx.Pipe()
        p = ctx.Process(target=clients_role, args=(ws_url, n, kind, child), daemon=True)
        p.start()
        pipes.append(parent)
        procs.append(p)
    try:
        joined = 0
        for c in pipes:
            if not c.poll(360):
                raise SystemExit(f"{kind}: the clients did not all join within 6 minutes")
            joined += c.recv()[1]
        time.sleep(2.0)  # joins settled
        load = uptime()
        cpu0 = {k: cpu_seconds(v) for k, v in pids.items()}
        t0 = time.monotonic()
        for c in pipes:
            c.send("go")
        sub: dict[bytes, float] = {}
        sub_times(router, pub_port, seconds, sub_gateway_key if kind == "gateway" else peer_key, sub)
        took = time.monotonic() - t0
        cpu = {k: round((cpu_seconds(v) - cpu0[k]) / took, 3) for k, v in pids.items()}
        time.sleep(0.5)  # the last messages reach the clients
        for c in pipes:
            c.send("stop")
        samples: list[tuple[bytes, float, float]] = []
        stats: list[dict[str, int]] = []
        for c in pipes:
            s, st = c.recv()
            samples += s
            stats.append(st)
    finally:
        for p in procs:
            p.join(30)
            if p.is_alive():
                p.kill()
    added = [(tk - sub[k]) * 1000 for k, tk, _ in samples if sub.get(k, -1.0) >= 0]
    in_process = [(tu - sub[k]) * 1000 for k, _, tu in samples if sub.get(k, -1.0) >= 0]
    return {"server": kind, "clients": joined, "samples": len(added), "unmatched": len(samples) - len(added),
            "added_ms_p50": round(pct(added, 50), 2), "added_ms_p99": round(pct(added, 99), 2),
            "added_ms_max": round(max(added, default=float("nan")), 2),
            "in_client_process_ms_p50": round(pct(in_process, 50), 2),
            "in_client_process_ms_p99": round(pct(in_process, 99), 2),
            "messages_per_client": [min(s["messages_min"] for s in stats), max(s["messages_max"] for s in stats)],
            "states_during": sum(s["states"] for s in stats),
            "cpu_cores": cpu, "uptime": load}


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


#: Added latency p99 targets (ms) by number of clients (issue 31).
FANOUT_TARGET = {200: 5.0, 1000: 10.0}


def fanout_target(clients: int) -> float:
    """The p99 target for this many clients (the next larger measured count's, issue 31)."""
    return next((v for k, v in sorted(FANOUT_TARGET.items()) if clients <= k), 10.0)


def export_tree(rev: str, into: Path) -> Path:
    """The ``robo_comp`` package of git revision ``rev`` under ``into`` (for ``PYTHONPATH``)."""
    root = Path(__file__).resolve().parents[1]
    archive = subprocess.run(["git", "-C", str(root), "archive", rev, "robo_comp"], capture_output=True,
                             check=True).stdout
    into.mkdir(parents=True, exist_ok=True)
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return into


def run_fanout(ref: Client, core: Any, web: Any, url: str, state: Path,
               args: argparse.Namespace) -> tuple[list[Any], bool]:
    """The gateway, the peer (and the gateway of ``--baseline``), one after the other, at every
    ``--clients`` count, against the same match."""
    servers = [("gateway", url, web)]
    for name in args.peers:
        proc, u = start_peer(pub_url(ref.url, int(ref.info["pub_port"])), PEERS[name])
        servers.append((name, u, proc))
    if args.baseline:
        tree = export_tree(args.baseline, state.parent / "baseline")
        old, old_url = start_web("--core", str(state), pythonpath=tree)
        servers.append((f"before ({args.baseline})", old_url, old))
    out, ok = [], True
    try:
        pids = {"core": core.pid, **{name.split()[0]: p.pid for name, _, p in servers}}
        for n in args.clients:
            row = {}
            for name, u, _ in servers:
                r = measure_fanout(ref, pids, u, "peer" if name in PEERS else "gateway", n, args.seconds)
                r["server"] = name
                print(f"fan-out, {name}, {n} clients:", json.dumps(r), flush=True)
                out.append(r)
                row[name] = r
            gw = row["gateway"]
            target = fanout_target(n)
            print(f"== {n} clients, added latency p50/p99 (ms): "
                  + ", ".join(f"{k} {r['added_ms_p50']:.2f}/{r['added_ms_p99']:.2f}" for k, r in row.items())
                  + f" (target gateway p99 < {target:g} ms); {gw['uptime']}", flush=True)
            ok &= gw["added_ms_p99"] < target
    finally:
        stop_all([p for _, _, p in servers[1:]], timeout=10)  # type: ignore[list-item]
    return out, ok


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robots", type=int, default=1000)
    ap.add_argument("--clients", "--browsers", type=int, nargs="+", default=[200, 1000],
                    help="WebSocket clients of the fan-out figure (each count measured on the gateway and the peer)")
    ap.add_argument("--seconds", type=float, default=15.0)
    ap.add_argument("--minutes", type=float, default=30.0, help="length of the synthetic log for the seek figure")
    ap.add_argument("--only", choices=["live", "fanout", "seek"])
    ap.add_argument("--debug-robots", type=int, default=100,
                    help="robots with debug drawing at the per-tick bound in the third drawing run (0: no such run)")
    ap.add_argument("--skip-fanout", action="store_true", help="only the drawing figures of the live part")
    ap.add_argument("--baseline", metavar="REV", default="",
                    help="also measure the fan-out of the gateway of this git revision (e.g. 8820265, before issue 31)")
    ap.add_argument("--peers", nargs="*", choices=sorted(PEERS), default=sorted(PEERS),
                    help="the bare broadcasters measured beside the gateway (default: both)")
    ap.add_argument("--peer", metavar="PUB_URL", help=argparse.SUPPRESS)  # a peer's own process
    ap.add_argument("--peer-send", choices=sorted(set(PEERS.values())), default="frames", help=argparse.SUPPRESS)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    if args.peer:
        peer_main(args.peer, args.peer_send)
        return 0
    res: dict[str, Any] = {}
    ok = True
    if args.only in (None, "live", "fanout"):
        tmp = Path(tempfile.mkdtemp(prefix="bench_web_live_"))
        core, hosts, ref = start_live(tmp / "state", args.robots)
        web = None
        try:
            c0, t0 = cpu_seconds(core.pid), time.monotonic()
            time.sleep(args.seconds)
            res["core_cpu_without_gateway"] = (cpu_seconds(core.pid) - c0) / (time.monotonic() - t0)
            web, url = start_web("--core", str(tmp / "state"))
            if args.only != "fanout":
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
                print("core CPU without the gateway:", round(res["core_cpu_without_gateway"], 3), flush=True)
                res["fanout"], fan_ok = run_fanout(ref, core, web, url, tmp / "state", args)
                ok &= fan_ok
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
