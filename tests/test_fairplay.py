"""Fair play in a live match: the organiser owns the world, a team only gives commands (issue 25).

Every test attacks a real core process below the friendly client (raw pyzmq frames with a team's
own token, a misused host credential, a second host, a camera impostor) and checks that nothing
the attacker claims about the world is believed: no robot beyond the scenario, no pose a robot
could not have driven to, no victim scored that no robot of the team saw. ``docs/security.md``
("Fair play") names the defence each test checks.
"""
from __future__ import annotations

import json
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest
import zmq

from conftest import CoreHandle, wait_for, wait_robots
from robo_comp import protocol as P
from robo_comp.client import resolve_core
from robo_comp.protocol.curve import create_keys, load_secret, open_server
from robo_comp.robots.host import RobotHost
from robo_comp.world.scenario import default_scenario
from test_curve import curve_core  # noqa: F401  (a fixture: a --curve core whose keys robo-comp keys made)
from test_hostile_clients import Peer, code, router, sample_body

PNG = b"\x89PNG\r\n\x1a\n" + b"\x00" * 32
VICTIMS = [(v.x, v.y) for v in default_scenario().victims]  # the built-in arena's hidden victims


def _host(core: CoreHandle, team: str = "red", keys: Any = None) -> Peer:
    """A raw robot host that said hello with the organiser's host token of ``team``."""
    h = Peer(router(core), P.new_routing_id(), keys, token=core.host_token(team))
    assert h.own("hello", {"token": core.host_token(team), "client": "robots"})["ok"]
    return h


def _register(h: Peer, core: CoreHandle, robot_id: str, x: float, y: float, team: str = "red") -> int:
    reply = h.own("register", {"token": core.host_token(team), "robot_id": robot_id, "x": x, "y": y,
                               "heading": 0.0, "tasks": []})
    assert reply["ok"], reply
    return int(reply["body"]["tag"])


def _events(core: CoreHandle, topic: str) -> list[dict[str, Any]]:
    return [e["data"] for e in core.logged_events(topic)]


# ------------------------------------------------------------------ a team's token speaks for no one
def _team_token_attack(core: CoreHandle, keys: Any = None) -> None:
    """A team's own token, raw: every host message refused, no robot registered, nothing scored."""
    red_host = _host(core, "red", _organiser_keys(core) if keys is not None else None)
    tag = _register(red_host, core, "red-1", 2.0, 2.0)  # red's real robot, far from every victim
    team = Peer(router(core), P.new_routing_id(), keys, token=core.token("red"))
    assert team.own("hello", {"token": core.token("red"), "client": "attacker"})["ok"]
    for type_ in sorted(P.HOST_ONLY):
        body = dict(sample_body(type_), tag=tag) if "tag" in P.REQUESTS[type_] else sample_body(type_)
        if type_ == "register":
            body = {"token": core.token("red"), "robot_id": "ghost", "x": 11.0, "y": 9.0}
        reply = team.ask(type_, body, secret=team.session)
        assert code(reply) == "E_FORBIDDEN", (type_, reply)
        assert "host" in reply["error"]["message"]
    # a fresh connection that opens with register, the team's token and then the referee's
    for token in (core.token("red"), core.token("referee")):
        fresh = Peer(router(core), P.new_routing_id(), keys, token=token)
        # (under CurveZMQ the referee's token with red's key is refused even before: E_AUTH)
        assert code(fresh.ask("register", {"token": token, "robot_id": "ghost", "x": 11.0, "y": 9.0})) in (
            ("E_FORBIDDEN",) if keys is None or token == core.token("red") else ("E_FORBIDDEN", "E_AUTH"))
        fresh.close()
    # pictures claimed from next to each victim, then finds citing them: nothing to cite, nothing scored
    for vx, vy in VICTIMS:
        reply = team.ask("picture", {"tag": tag, "x": vx - 1.0, "y": vy, "heading": 0.0, "png": PNG},
                         secret=team.session)
        assert code(reply) == "E_FORBIDDEN"
        find = team.own("find", {"tag": tag, "x": vx, "y": vy, "kind": "adult", "evidence": []})
        assert not find["ok"] or find["body"]["state"] != "confirmed", find
    ref = core.referee()
    assert [r["robot_id"] for r in ref.robots()] == ["red-1"]  # no robot beyond what the host registered
    assert {r["team"]: r["score"] for r in ref.request("score")["teams"]}["red"] <= 0
    assert _events(core, "picture") == []
    m = ref.monitor(tag)
    assert (m["x"], m["y"]) == (2.0, 2.0)  # no report of the team's moved it
    team.close()
    red_host.close()


def _organiser_keys(core: CoreHandle) -> Any:
    from robo_comp.protocol.curve import client_keys

    return client_keys(str(core.state), core.host_token("red"))


def test_a_team_token_cannot_register_report_or_picture_and_scores_nothing(core: CoreHandle) -> None:
    """Defence: the role table (``protocol.ROLE_MESSAGES``): a team's token gives commands and
    reads its own robots; every message that speaks for the world is the organiser's hosts' only."""
    _team_token_attack(core)


def test_the_same_attack_under_curve_with_the_teams_own_key(curve_core: CoreHandle) -> None:  # noqa: F811
    """Defence: the role table holds under CurveZMQ too, and a team's key never opens a host session."""
    from robo_comp.protocol.curve import client_keys

    red_keys = client_keys(str(curve_core.state), curve_core.token("red"))
    assert red_keys is not None
    _team_token_attack(curve_core, red_keys)
    # the host token with the team's key (not the organiser's): refused before any robot is registered
    h = Peer(router(curve_core), P.new_routing_id(), red_keys, token=curve_core.host_token("red"))
    reply = h.ask("register", {"token": curve_core.host_token("red"), "robot_id": "ghost", "x": 2.0, "y": 2.0})
    assert code(reply) == "E_AUTH" and "organiser" in reply["error"]["message"]
    h.close()


# ------------------------------------------------------------------ registration within the scenario
def test_a_team_gets_the_robots_the_scenario_gives_it_and_no_more(core: CoreHandle) -> None:
    """Defence: ``Core.robot_limit``: the built-in arena gives each team 3 robots; a 4th robot id
    is refused with a sentence, and a robot that comes back with its old id is welcome."""
    h = _host(core)
    tags = [_register(h, core, f"red-{i}", 1.0 + i, 2.0) for i in range(1, 4)]
    reply = h.ask("register", {"token": core.host_token("red"), "robot_id": "red-4", "x": 2.0, "y": 3.0},
                  secret=h.session)
    assert code(reply) == "E_FORBIDDEN"
    assert "3 robots" in reply["error"]["message"] and "--robots" in reply["error"]["message"]
    assert _register(h, core, "red-2", 2.0, 2.0) == tags[1]  # the same robot again: its tag
    # a new robot must start somewhere a robot can be
    h2 = _host(core, "blue")
    for x, y, why in ((40.0, 3.0, "outside"), (0.0, 0.0, "wall")):
        reply = h2.ask("register", {"token": core.host_token("blue"), "robot_id": "b-x", "x": x, "y": y},
                       secret=h2.session)
        assert code(reply) == "E_IMPLAUSIBLE" and why in reply["error"]["message"], reply
    assert len(core.referee().robots()) == 3
    h.close()
    h2.close()


# ------------------------------------------------------------------ poses: only what a robot can drive
def test_teleports_wall_poses_and_creeping_jumps_are_refused_and_shown_to_the_referee(core: CoreHandle) -> None:
    """Defence: ``robo_comp.match.plausibility.PoseGate`` on every ``report``/``reports`` row: out of
    the arena, inside a wall, or farther than the robot's driving budget since the last pose taken."""
    h = _host(core)
    tag = _register(h, core, "red-1", 2.0, 2.0)
    ref = core.referee()
    ref.watch(True)
    far = max(((x, y) for y in range(20) for x in range(24) if not default_scenario().walls[y, x]),
              key=lambda c: abs(c[0] - 2) + abs(c[1] - 2))
    bad = [("report", {"tag": tag, "x": float(far[0]), "y": float(far[1]), "heading": 0.0}, "jump"),
           ("report", {"tag": tag, "x": 2.0, "y": 0.0, "heading": 0.0}, "wall"),
           ("reports", {"tags": [tag], "x": [-3.0], "y": [2.0], "heading": [0.0]}, "outside"),
           # 11 cells down the free column with a huge sigma: 3 sigma would cover it, but sigma counts at
           # most 0.5 cells (budget 7.5 + noise 1.5 < 11)
           ("reports", {"tags": [tag], "x": [2.0], "y": [13.0], "heading": [0.0], "sigma": [1e9]}, "jump")]
    for type_, body, why in bad:
        reply = h.ask(type_, body, secret=h.session)
        assert code(reply) == "E_IMPLAUSIBLE" and why in reply["error"]["message"], reply
        m = ref.monitor(tag)
        assert (m["x"], m["y"]) == (2.0, 2.0), (type_, m)
    # creeping: 60 jumps of half a cell (30 cells along free cells) as fast as they can be sent; the
    # robot drives 2 cells/s
    t0 = time.monotonic()
    path = [(2.0 + 0.5 * k, 2.0) for k in range(1, 41)] + [(22.0, 2.0 + 0.5 * k) for k in range(1, 21)]
    for x, y in path:
        h.send("reports", {"tags": [tag], "x": [x], "y": [y], "heading": [0.0]}, secret=h.session)
    time.sleep(0.3)
    elapsed = time.monotonic() - t0
    replies = h.listen(0.5)
    refused = [m for m in replies if m.get("type") == "reply" and not m.get("ok")]
    assert refused, "the creeping teleport was taken whole"
    m = ref.monitor(tag)
    moved = abs(m["x"] - 2.0) + abs(m["y"] - 2.0)
    assert moved <= 2.0 * (elapsed + 3.0) + 1.5 + 1e-6  # speed x time + the budget's capacity
    wait_for(lambda: _events(core, "integrity"), 3.0, "the referee's integrity event")
    rows = _events(core, "integrity")
    assert all(r["tag"] == tag and r["kind"] == "pose" for r in rows) and sum(r["count"] for r in rows) >= 4
    # a plausible move is taken (once the budget the attack spent has filled again, as a host reports on)
    here = ref.monitor(tag)

    said = []

    def moved_on() -> bool:
        said.append(h.ask("report", {"tag": tag, "x": here["x"], "y": here["y"] + 1.0, "heading": 90.0},
                          secret=h.session, timeout=0.2))
        return bool(ref.monitor(tag)["y"] == here["y"] + 1.0)

    wait_for(moved_on, 10.0, f"a move the robot can make {here} {said[-1:]}")
    h.close()


def test_poses_hopping_about_near_where_the_robot_stands_are_refused(core: CoreHandle) -> None:
    """Defence: the hop rule of ``PoseGate.admit`` and the core's ``reports`` loop. Every pose lies
    two cells from where the robot stood, but four from the pose before, twenty times in a burst:
    a robot that drives 2 cells/s cannot, and a host that claims it gets the first hops only."""
    h = _host(core)
    tag = _register(h, core, "red-1", 8.0, 2.0)
    ref = core.referee()
    for k in range(20):
        x = 6.0 if k % 2 == 0 else 10.0
        h.send("reports", {"tags": [tag], "x": [x], "y": [2.0], "heading": [0.0]}, secret=h.session)
    time.sleep(0.3)
    refused = [m for m in h.listen(0.5) if m.get("type") == "reply" and not m.get("ok")]
    # taken: 6 (a hop of 2), 10 (of 4: 1.5 cells left); then each pose at 6 is refused, and each at 10
    # is where the robot was taken last
    assert len(refused) >= 8 and "a hop of 4.0 cells" in refused[-1]["error"]["message"], refused[-1:]
    assert all(code(m) == "E_IMPLAUSIBLE" for m in refused)
    wait_for(lambda: any(r["tag"] == tag and r["kind"] == "pose" for r in _events(core, "integrity")), 3.0,
             "the referee's integrity event")
    assert ref.monitor(tag)["x"] == 10.0
    h.close()


def test_pictures_and_finds_are_judged_where_the_robot_is_tracked(core: CoreHandle) -> None:
    """Defence: ``Core.judged_pose``: a picture is judged at the host's claimed pose only where the
    tracked pose bears it out (3 sigma + driving since the last report); a claim next to a victim
    from a robot tracked across the arena sees nothing, and a find citing it is not confirmed."""
    h = _host(core)
    tag = _register(h, core, "red-1", 2.0, 2.0)
    red = core.client("red")
    before = {r["team"]: r["score"] for r in red.request("score")["teams"]}["red"]
    for vx, vy in VICTIMS:
        reply = h.own("picture", {"tag": tag, "x": vx - 1.0, "y": vy, "heading": 0.0, "png": PNG})
        assert reply["ok"] and reply["body"]["seen"] == [], reply
        find = red.request("find", tag=tag, x=vx, y=vy, kind="adult", evidence=[reply["body"]["id"]])
        assert find["state"] != "confirmed", find
    assert {r["team"]: r["score"] for r in red.request("score")["teams"]}["red"] <= before
    wait_for(lambda: sum(r["count"] for r in _events(core, "integrity") if r["kind"] == "picture") == len(VICTIMS),
             3.0, "the referee's integrity events, one line a beat")
    rows = [r for r in _events(core, "integrity") if r["kind"] == "picture"]
    assert all("tracked" in r["message"] for r in rows)
    # a robot that drives there (plausible reports) and takes the picture: judged there, the victim seen
    vx, vy = VICTIMS[2]  # (4, 10): down the free column x = 3 from (2, 2)
    path = [(2.0, 2.0 + k * 0.2) for k in range(0, 41)] + [(2.0 + k * 0.2, 10.0) for k in range(1, 5)]
    for x, y in path:
        h.send("report", {"tag": tag, "x": x, "y": y, "heading": 0.0}, secret=h.session)
        time.sleep(0.1)  # 2 cells a second: the robot's speed
    wait_for(lambda: core.referee().monitor(tag)["x"] > 2.7, 5.0, "the robot tracked next to the victim")
    reply = h.own("picture", {"tag": tag, "x": 2.8, "y": 10.0, "heading": 0.0, "png": PNG})
    assert reply["ok"] and {(s["x"], s["y"]) for s in reply["body"]["seen"]} == {(vx, vy)}, reply
    h.close()


# ------------------------------------------------------------------ a second host
def test_a_second_host_for_the_same_robots_is_refused_and_the_first_goes_on(core: CoreHandle) -> None:
    """Defence: ``E_HELD``: robots connected through one host are not taken by another (it waits,
    quietly, and the referee hands them over with ``ctl hosts``/``ctl handover``); the first host's
    robots go on reporting, and the refusals reach the referee folded (one line a beat)."""
    first = core.robots("red", 2)
    red = core.client("red")
    rows = wait_robots(red, 2)
    tags = sorted(r["tag"] for r in rows)
    second = core.robots("red", 2)  # the organiser types the command twice
    log2 = core.state / "robots-red.log"
    wait_for(lambda: "held by another robot host" in log2.read_text(), 20, "the second host told why")
    seen = {t: red.monitor(t)["last_report"] for t in tags}
    time.sleep(2.0)  # both hosts run; the first keeps its robots and reports on
    for t in tags:
        m = red.monitor(t)
        assert m["status"] == "connected" and m["last_report"] > seen[t], m
    assert log2.read_text().count("held by another robot host") == 2  # said once per robot, not every beat
    refused = [e for e in core.logged_events("refused") if e["data"].get("type") in ("report", "reports")]
    assert refused == [], refused  # the first host is not refused anything
    ctl = [sys.executable, "-m", "robo_comp.cli", "ctl", "--core", str(core.state), "--token-file",
           str(core.token_file("referee"))]
    hosts = json.loads(subprocess.run([*ctl, "--json", "hosts"], capture_output=True, text=True,
                                      timeout=30).stdout)
    holding = [h for h in hosts if h["tags"]]
    assert len(holding) == 1 and holding[0]["tags"] == tags and holding[0]["team"] == "red"
    # the team's own token cannot see or move hosts
    out = subprocess.run([sys.executable, "-m", "robo_comp.cli", "ctl", "--core", str(core.state), "--token-file",
                          str(core.token_file("red")), "handover", str(tags[0])], capture_output=True, text=True,
                         timeout=30)
    assert out.returncode == 1 and "E_FORBIDDEN" in out.stderr
    # the referee hands the robots over: the waiting host takes them, the first lets them go
    out = subprocess.run([*ctl, "handover", ",".join(map(str, tags))], capture_output=True, text=True, timeout=30)
    assert out.returncode == 0, out.stderr
    wait_for(lambda: "this host runs it now" in log2.read_text(), 20, "the second host took over")
    assert "handed this robot over" in log2.read_text()

    def new_holder() -> bool:
        now = json.loads(subprocess.run([*ctl, "--json", "hosts"], capture_output=True, text=True,
                                        timeout=30).stdout)
        return [h["host"] for h in now if h["tags"] == tags] not in ([], [holding[0]["host"]])

    wait_for(new_holder, 10, "the robots with the second host")
    wait_robots(red, 2)
    assert first.poll() is None and second.poll() is None  # both hosts still run, neither crashed


# ------------------------------------------------------------------ the camera
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_fixes_come_only_from_the_organisers_camera_and_only_where_the_robot_can_be(core: CoreHandle) -> None:
    """Defence: the camera's PUB is a CurveZMQ server under the organiser's key, pinned by the hosts
    (``robots --camera-key``): an impostor bound at the camera's address gets no fix through; and
    the host's own ``PoseGate`` refuses a fix the robot could not have driven to."""
    create_keys(core.state, ["red", "blue"])
    url = f"tcp://127.0.0.1:{_free_port()}"
    ctx = zmq.Context.instance()
    impostor = ctx.socket(zmq.PUB)  # whoever binds the camera's address first: no key
    impostor.setsockopt(zmq.LINGER, 0)
    impostor.bind(url)
    host = RobotHost(resolve_core(str(core.state)), core.host_token("red"), 1, positioning=url,
                     camera_key=core.state / "keys" / "organiser.key")
    th = threading.Thread(target=host.run, kwargs={"duration": 40}, daemon=True)
    th.start()
    try:
        red = core.client("red")
        tag = wait_robots(red, 1)[0]["tag"]
        start = red.monitor(tag)
        t_end = time.monotonic() + 2.0
        while time.monotonic() < t_end:
            impostor.send_multipart([b"fixes", P.pack({"t": time.time(), "seq": 0, "fixes": [
                {"robot": "red-1", "x": 20.0, "y": 15.0, "heading": 0.0, "sigma": 0.01, "cameras": [0]}]})])
            time.sleep(0.05)
        assert host.camera_fixes == 0, "a fix from a program without the organiser's key was taken"
        impostor.close(0)
        time.sleep(0.3)
        camera = ctx.socket(zmq.PUB)  # the organiser's camera, with the organiser's key
        camera.setsockopt(zmq.LINGER, 0)
        open_server(camera, *load_secret(core.state / "keys" / "organiser.key_secret"))
        camera.bind(url)
        try:
            t_end = time.monotonic() + 10.0
            while host.fixes_refused == 0 and time.monotonic() < t_end:  # a jump across the arena
                camera.send_multipart([b"fixes", P.pack({"t": time.time(), "seq": 1, "fixes": [
                    {"robot": "red-1", "x": 20.0, "y": 15.0, "heading": 0.0, "sigma": 0.01, "cameras": [0]}]})])
                time.sleep(0.05)
            assert host.fixes_refused >= 1 and host.camera_fixes == 0
            m = red.monitor(tag)
            assert abs(m["x"] - start["x"]) + abs(m["y"] - start["y"]) < 1.0, m
            near = (start["x"] + 0.3, start["y"])
            t_end = time.monotonic() + 10.0
            while host.camera_fixes == 0 and time.monotonic() < t_end:  # a fix where it can be: taken
                camera.send_multipart([b"fixes", P.pack({"t": time.time(), "seq": 2, "fixes": [
                    {"robot": "red-1", "x": near[0], "y": near[1], "heading": 0.0, "sigma": 0.01, "cameras": [0]}]})])
                time.sleep(0.05)
            assert host.camera_fixes >= 1
        finally:
            camera.close(0)
    finally:
        host.stop()
        th.join(5)


def test_a_host_refuses_to_take_fixes_without_the_cameras_key(core: CoreHandle, tmp_path: Path) -> None:
    """Defence: no unauthenticated positioning at all: ``--positioning camera:URL`` without the
    camera's public key is a clear error before anything connects."""
    out = subprocess.run([sys.executable, "-m", "robo_comp.cli", "robots", "--core", str(core.state),
                          "--token-file", str(core.host_token_file("red")), "--count", "1",
                          "--positioning", f"camera:tcp://127.0.0.1:{_free_port()}"],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode != 0 and "--camera-key" in out.stderr and "Traceback" not in out.stderr, out.stderr


@pytest.mark.parametrize("speed", [2.0, 50.0])
def test_a_host_declared_speed_is_cut_to_the_cores_limit(core: CoreHandle, speed: float) -> None:
    """Defence: a host's declared top speed is cut to ``--max-speed`` (default 4x the scenario's):
    a host cannot widen its own robots' driving budget by claiming a fast robot."""
    h = _host(core)
    reply = h.own("register", {"token": core.host_token("red"), "robot_id": "red-1", "x": 1.0, "y": 1.0,
                               "speed": speed, "tasks": []})
    tag = reply["body"]["tag"]
    ref = core.referee()
    # 27 cells at once, across the arena: more than even the fastest robot's budget (8 x 3 + 1.5 cells)
    r = h.ask("report", {"tag": tag, "x": 22.0, "y": 18.0, "heading": 0.0}, secret=h.session, timeout=1.0)
    assert code(r) == "E_IMPLAUSIBLE" and (ref.monitor(tag)["x"], ref.monitor(tag)["y"]) == (1.0, 1.0)
    # 10 cells at once: too far for 2 cells/s (7.5 cells of budget), within reach at the cut 8 cells/s
    r = h.ask("report", {"tag": tag, "x": 1.0, "y": 11.0, "heading": 0.0}, secret=h.session, timeout=1.0)
    if speed == 2.0:
        assert code(r) == "E_IMPLAUSIBLE" and ref.monitor(tag)["y"] == 1.0
    else:
        assert r is None and ref.monitor(tag)["y"] == 11.0
    h.close()


def test_host_tokens_are_the_organisers_private_files(core: CoreHandle) -> None:
    """Defence: ``TokenBook``: host tokens are 0600 in a 0700 folder of the state folder."""
    import stat

    hosts = core.state / "hosts"
    assert stat.S_IMODE(hosts.stat().st_mode) == 0o700
    for team in ("red", "blue"):
        f = core.host_token_file(team)
        assert stat.S_IMODE(f.stat().st_mode) == 0o600 and len(f.read_text().strip()) >= 16
        assert f.read_text().strip() != core.token(team)
