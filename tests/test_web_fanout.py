"""The web gateway's fan-out (issue 31): a frame made once reaches every browser of its view as
the same bytes, a browser that does not read gets the newest poses instead of a backlog, and one
that stays behind gets a fresh state; a team's view still carries nothing of another team.

A real core with real robot hosts, the gateway's app on uvicorn with its own WebSocket protocol
(:func:`robo_comp.web.wire.config`) on real sockets, real WebSocket clients. The gateway runs in a
thread of this process so that the test can see which frames its views made and what waits for
each browser; the large position batches of the slow-browser test are put into the public view
as its feed would (a thousand robots' worth, which two robot hosts in a test do not make).
"""
from __future__ import annotations

import asyncio
import json
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("starlette", reason="the web extra is not installed (pip install -e '.[web]')")

from conftest import wait_for, wait_robots  # noqa: E402
from robo_comp.testing import Match, start_match  # noqa: E402
from test_web import drive_far  # noqa: E402


class Gateway:
    """The live gateway's app served by uvicorn (:func:`robo_comp.web.wire.config`) in a thread of
    this process, on a free port of 127.0.0.1."""

    def __init__(self, m: Match) -> None:
        import uvicorn

        from robo_comp.web.server import LiveGateway, make_app
        from robo_comp.web.wire import config

        self.gw = LiveGateway(str(m.state), m.token("referee"))
        sock = socket.socket()
        sock.bind(("127.0.0.1", 0))
        sock.listen(128)
        self.url = f"ws://127.0.0.1:{sock.getsockname()[1]}/ws"
        self.server = uvicorn.Server(config(make_app(self.gw)))
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_until_complete,
                                       args=(self.server.serve(sockets=[sock]),), daemon=True)
        self.thread.start()
        wait_for(lambda: self.server.started, 20, "the gateway to serve")

    def call(self, fn: Any, *args: Any) -> Any:
        """``fn(*args)`` on the gateway's event loop; its result."""
        async def run() -> Any:
            return fn(*args)
        return asyncio.run_coroutine_threadsafe(run(), self.loop).result(10)

    async def acall(self, fn: Any, *args: Any) -> Any:
        """:meth:`call` from another event loop."""
        async def run() -> Any:
            return fn(*args)
        return await asyncio.wrap_future(asyncio.run_coroutine_threadsafe(run(), self.loop))

    def close(self) -> None:
        self.server.should_exit = True
        self.thread.join(15)


@pytest.fixture(scope="module")
def fan(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Match, Gateway]]:
    """A core (demo room, practice) with two driving robots each for red and blue, and the gateway."""
    m = start_match(tmp_path_factory.mktemp("fanout") / "state", teams=["red", "blue"])
    g = None
    try:
        m.robots("red", 2)
        m.robots("blue", 2)
        for team in ("red", "blue"):
            wait_robots(m.client(team), 2)
            drive_far(m.client(team))
        g = Gateway(m)
        yield m, g
    finally:
        if g is not None:
            g.close()
        m.close()


async def join(url: str, token: str | None = None, **kw: Any) -> Any:
    """A WebSocket client of the gateway that joined a view (public, or ``token``'s) and read its state."""
    import websockets

    ws = await websockets.connect(url, compression=None, max_size=None, **kw)
    assert json.loads(await ws.recv())["type"] == "hello"
    await ws.send(json.dumps({"op": "join", **({"token": token} if token else {})}))
    while True:
        msg = json.loads(await ws.recv())
        if msg["type"] == "state":
            return ws


def poses(tags: list[int], step: int, team: str = "green") -> tuple[str, dict[str, Any]]:
    """A position batch of the public feed's kind (robots that are not in the match: the page
    draws them; nothing of a real team is involved)."""
    n = len(tags)
    return ("robot.positions", {"team": team, "tags": tags, "x": [1.0 + i % 20 + step / 100 for i in range(n)],
                                "y": [2.0 + i // 20 for i in range(n)], "heading": [float(step % 360)] * n,
                                "moving": [True] * n, "sigma": [0.1] * n})


def test_a_frame_is_made_once_and_every_browser_of_the_view_gets_its_bytes(fan) -> None:
    """Four browsers on the public view and one on red's: every frame the public view made
    while they watched reached each public browser, in order, as the very bytes the view
    framed; red's browser got the frames red's view made, with none of blue's robots."""
    from robo_comp.web.hub import Frame, Hub
    from robo_comp.web.wire import TransportWire, frame_text

    m, g = fan
    blue = {r["tag"] for r in m.client("blue").robots()}
    made: list[tuple[str, bytes]] = []
    original = Hub.fan_out

    def recording(hub: Hub, frame: Frame) -> None:
        made.append((hub.kind, frame.data))
        original(hub, frame)

    async def scenario() -> tuple[list[list[bytes]], int, bool]:
        await g.acall(setattr, Hub, "fan_out", recording)
        try:
            public = [await join(g.url) for _ in range(4)]
            red = await join(g.url, m.token("red"))
            got: list[list[bytes]] = [[] for _ in range(5)]

            async def read(i: int, ws: Any) -> None:
                async for text in ws:
                    got[i].append(text.encode())

            readers = [asyncio.create_task(read(i, ws)) for i, ws in enumerate([*public, red])]
            mark = len(made)  # every browser is in: each frame from here on is for all of its view
            await asyncio.sleep(3.0)  # the robots drive: ten position batches a team a second
        finally:
            await g.acall(setattr, Hub, "fan_out", original)
        last = [f for kind, f in made if kind == "public"][-1]
        t_end = time.monotonic() + 20
        while not all(any(last == frame_text(x) for x in got[i][-3:]) for i in range(4)) and time.monotonic() < t_end:
            await asyncio.sleep(0.05)
        wires = await g.acall(lambda: {type(s.wire) for h in [g.gw.public, *g.gw.private.values()]
                                       for s in h.subs})
        for r in readers:
            r.cancel()
        for ws in [*public, red]:
            await ws.close()
        return got, mark, len(wires) == 1 and TransportWire in wires

    got, mark, direct = asyncio.run(scenario())
    assert direct  # every browser's frames went straight to its socket (the gateway's own protocol)
    frames = [f for kind, f in made[mark:] if kind == "public"]
    red_made = [f for kind, f in made if kind == "private"]
    assert len(frames) >= 10 and len(set(frames)) == len(frames)
    for i in range(4):  # each public browser: every frame made meanwhile, in order, byte for byte
        framed = [frame_text(t) for t in got[i]]
        first = framed.index(frames[0])
        assert framed[first:first + len(frames)] == frames
    assert red_made and {frame_text(t) for t in got[4] if json.loads(t)["type"] == "ev"} <= set(red_made)
    seen_blue = {tag for t in got[0] for _, d, *_ in json.loads(t).get("e", []) for tag in d.get("tags", [])}
    assert seen_blue & blue  # the public view shows blue (so the check below can fail)
    for t in got[4]:
        for topic, d, *_ in json.loads(t).get("e", []):
            assert not (set(d.get("tags") or []) & blue) and d.get("tag") not in blue and d.get("team") != "blue", topic


def test_a_browser_that_does_not_read_gets_the_newest_poses_not_a_backlog(fan) -> None:
    """A browser that stops reading (a small receive buffer, nothing read) while the public view
    sends a thousand robots' poses (all of them, then each half in turn): the other browser gets
    every frame; the frames for the stalled one wait, and a waiting frame of poses goes once later
    ones place all its robots; when it reads again it gets what was in flight and then the newest
    poses, every other event kept, in order. One that falls further behind than the frames held
    for it gets a fresh state instead."""
    import websockets

    from robo_comp.web.hub import HELD_FRAMES

    m, g = fan
    tags = list(range(5000, 6000))

    async def publish(events: list[tuple[str, dict[str, Any]]]) -> None:
        await g.acall(g.gw.public.publish, events)

    async def scenario() -> dict[str, Any]:
        fast = await join(g.url)
        small = socket.socket()
        small.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # before connecting: a small window
        small.connect(("127.0.0.1", int(g.url.split(":")[2].split("/")[0])))
        slow = await join(g.url, sock=small, max_queue=1)  # reads nothing unless asked

        def slow_sub() -> Any:
            me = small.getsockname()
            return next(s for s in g.gw.public.subs if s.wire.transport.get_extra_info("peername") == me)

        fast_got: list[str] = []

        async def read_fast() -> None:
            async for text in fast:
                fast_got.append(text)

        reader = asyncio.create_task(read_fast())
        for i in range(150):  # ~33 KiB a frame: the stalled browser's socket fills after a few
            await publish([poses([tags, tags[:500], tags[500:]][i % 3], i)])  # all; one half; the other
            if i % 30 == 29:
                await publish([("broadcast", {"message": f"kept {i}"})])
            await asyncio.sleep(0.002)
        sub = await g.acall(slow_sub)
        held = await g.acall(lambda: (len(sub.held), sub.conflated, sub.behind, sum(
            1 for i, f in enumerate(sub.held)  # held frames of poses whose robots later ones all place
            if f.poses and f.poses <= frozenset().union(*(h.poses for h in sub.held[i + 1:] if h.poses)))))
        last = '"message":"kept 149"'  # the last frame's mark
        wait_until = time.monotonic() + 30
        while not any(last in t for t in fast_got[-50:]) and time.monotonic() < wait_until:
            await asyncio.sleep(0.05)
        slow_got: list[str] = []
        wait_until = time.monotonic() + 30
        while not (slow_got and last in slow_got[-1]) and time.monotonic() < wait_until:  # it reads again
            slow_got.append(await asyncio.wait_for(slow.recv(), 20))
        fast_then = list(fast_got)
        # further behind than the frames held for it: a state instead
        for i in range(HELD_FRAMES * 3):  # 4 KiB each: more than the socket's buffers hold
            await publish([("broadcast", {"message": f"flood {i} " + "x" * 4096})])
        behind = await g.acall(lambda: sub.behind)
        after: list[dict[str, Any]] = []
        wait_until = time.monotonic() + 30
        while (not after or after[-1]["type"] != "state") and time.monotonic() < wait_until:
            after.append(json.loads(await asyncio.wait_for(slow.recv(), 20)))
        resyncs = await g.acall(lambda: sub.resyncs)
        reader.cancel()
        for ws in (fast, slow):
            await ws.close()
        return {"held": held, "fast": fast_then, "slow": slow_got, "behind": behind, "after": after,
                "resyncs": resyncs}

    r = asyncio.run(scenario())
    held, conflated, behind, redundant = r["held"]
    assert conflated > 50 and 1 <= held < 40 and not behind  # waiting: a few frames, not the backlog
    assert redundant == 0  # a frame of every robot went once the two halves after it came
    fast, slow = r["fast"], r["slow"]
    ours = [t for t in fast if '"green"' in t or '"kept ' in t]
    assert len(ours) == 155  # the reading browser got every frame
    assert len(slow) < len(fast) - 10
    it = iter(fast)  # the stalled browser's frames: the reading one's, in the same order, some left out
    assert all(any(t == f for f in it) for t in slow)
    missed = [t for t in ours if t not in slow]
    assert missed and all(json.loads(t)["e"][0][0] == "robot.positions" for t in missed)  # only poses
    assert [t for t in ours if '"kept ' in t] == [t for t in slow if '"kept ' in t]
    newest = [t for t in fast if '"green"' in t][-1]
    assert '"heading":[149.0,' in newest and newest in slow  # it got the newest poses
    assert r["behind"] and r["resyncs"] == 1
    state = r["after"][-1]["state"]
    assert state["messages"][-1]["text"].startswith(f"flood {HELD_FRAMES * 3 - 1} ")  # the state holds the newest
    flood = [int(msg["e"][0][1]["message"].split()[1]) for msg in r["after"] if msg["type"] == "ev"
             and msg["e"][0][0] == "broadcast"]
    assert flood == list(range(len(flood))) and len(flood) < HELD_FRAMES * 3  # what was in flight, then the state


def test_a_session_back_on_the_same_core_sends_no_fresh_state(fan) -> None:
    """The public view's session times out (the core stopped longer than the link's silence) and
    comes back to the same core process: its browsers keep their frames and get no fresh state
    (the view kept its feed; a state for each of a thousand browsers is hundreds of MiB), and the
    match goes on in their frames. A restarted core still sends one
    (``test_web.py::test_gateway_follows_a_core_restart``)."""
    import signal

    m, g = fan
    for team in ("red", "blue"):
        drive_far(m.client(team))

    async def scenario() -> tuple[int, int, list[dict[str, Any]]]:
        ws = await join(g.url)
        before = await g.acall(lambda: g.gw.public.link.reconnects)
        m.proc.send_signal(signal.SIGSTOP)
        try:
            await asyncio.sleep(3.5)  # past the link's silence (2 s with the test core's 0.2 s heartbeat)
        finally:
            m.proc.send_signal(signal.SIGCONT)
        got: list[dict[str, Any]] = []  # everything since the core went on
        t_end = time.monotonic() + 30
        back = 0
        while time.monotonic() < t_end:
            try:
                got.append(json.loads(await asyncio.wait_for(ws.recv(), 0.5)))
            except asyncio.TimeoutError:
                pass
            if not back and await g.acall(lambda: g.gw.public.link.reconnects) > before:
                back = len(got)
            if back and sum(1 for msg in got[back:] if msg["type"] == "ev") >= 5:
                await asyncio.sleep(1.0)  # a fresh state, if one came, would be here by now
                while True:
                    try:
                        got.append(json.loads(await asyncio.wait_for(ws.recv(), 0.2)))
                    except asyncio.TimeoutError:
                        break
                break
        after = await g.acall(lambda: g.gw.public.link.reconnects)
        await ws.close()
        return before, after, got

    before, after, since = asyncio.run(scenario())
    assert after > before  # the session did time out and come back
    assert sum(1 for msg in since if msg["type"] == "ev") >= 5  # the match goes on in the same frames
    assert [msg["type"] for msg in since if msg["type"] != "ev"] == []
