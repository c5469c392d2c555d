"""The overhead-camera positioning system: synthetic frames, calibration, detection, fusion,
the organiser's marker file, and real processes (core, robot host, camera) finishing goTo tasks
with positions seen only through synthetic camera frames."""
from __future__ import annotations

import math
import socket
import subprocess
import sys
import threading
import time

import cv2
import numpy as np
import pytest
import zmq

from robo_comp import protocol as P
from robo_comp.client import resolve_core
from robo_comp.protocol.curve import create_keys, load_secret, open_server
from robo_comp.errors import FieldError
from robo_comp.launch import start_robots, stop_all
from robo_comp.robots.host import RobotHost
from robo_comp.world.overhead import binding, calibrate, detect, fuse, synth
from robo_comp.world.overhead.source import Locator
from robo_comp.world.scenario import default_scenario
from tests.conftest import next_event_where, wait_robots

WALLS = default_scenario().walls.astype(bool)
H, W = WALLS.shape
FLOOR = synth.floor_markers(W, H)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _robots(n: int, seed: int = 3) -> list[tuple[int, float, float, float]]:
    rng = np.random.default_rng(seed)
    ys, xs = np.nonzero(~WALLS)
    k = rng.choice(len(xs), n, replace=False)
    return [(i, float(xs[j]) + rng.uniform(-0.3, 0.3), float(ys[j]) + rng.uniform(-0.3, 0.3),
             float(rng.uniform(0, 360))) for i, j in enumerate(k)]


def _calibrated(cam: synth.SyntheticCamera) -> calibrate.Calibration:
    return calibrate.calibrate(detect.Detector().detect(cam.render(WALLS, [], FLOOR)), FLOOR, cam.size)


@pytest.mark.parametrize("condition", list(synth.CONDITIONS))
def test_poses_from_synthetic_frames_match_the_truth(condition):
    cam = synth.cameras_for(W, H)[0]
    cal = _calibrated(cam)
    assert cal.error_cells < 0.02
    robots = _robots(20)
    frame = cam.render(WALLS, robots, FLOOR, degrade=synth.CONDITIONS[condition])
    assert frame.shape == (720, 1280)
    got = detect.poses(detect.Detector().detect(frame), cal.homography)
    seen = [(got[m], x, y, hd) for m, x, y, hd in robots if m in got]
    floor_seen = [m for m in got if m in FLOOR]
    assert len(floor_seen) >= len(FLOOR) // 2  # enough to calibrate from (the far ones are small)
    assert len(seen) >= (20 if synth.CONDITIONS[condition].occlude == 0 else 10), condition
    for p, x, y, hd in seen:
        assert math.hypot(p.x - x, p.y - y) < 0.1, (condition, p, x, y)  # 2.5 cm at 25 cm cells
        assert abs((p.heading - hd + 180) % 360 - 180) < 3.0
    assert not any(m not in FLOOR and m >= 20 for m in got)  # no marker that is not there


def test_a_moved_camera_is_noticed():
    cam = synth.cameras_for(W, H)[0]
    cal = _calibrated(cam)
    assert calibrate.drift(cal, detect.Detector().detect(cam.render(WALLS, [], FLOOR)), FLOOR) < 0.05
    moved = synth.SyntheticCamera(cam.view, tilt=0.18)  # knocked: it looks at the floor another way
    d = calibrate.drift(cal, detect.Detector().detect(moved.render(WALLS, [], FLOOR)), FLOOR)
    assert d is not None and d > calibrate.MOVED_CELLS


def test_calibration_needs_four_floor_markers_and_says_so():
    cam = synth.cameras_for(W, H)[0]
    found = detect.Detector().detect(cam.render(WALLS, [], dict(list(FLOOR.items())[:3])))
    with pytest.raises(FieldError, match="4 floor markers"):
        calibrate.calibrate(found, FLOOR, cam.size)


def test_two_overlapping_cameras_give_one_pose_per_robot():
    cams = synth.cameras_for(W, H, 2)
    cals = [_calibrated(c) for c in cams]
    robots = _robots(12, seed=5)
    b = binding.Bindings({m: f"red-{m + 1}" for m, *_ in robots}, FLOOR)
    located = Locator(b, cals).locate([c.render(WALLS, robots, FLOOR) for c in cams])
    assert set(located.fixes) == {f"red-{m + 1}" for m, *_ in robots}
    both = [p for p in located.fixes.values() if p.cameras == (0, 1)]
    assert both, "the overlap saw no robot twice"
    for m, x, y, _ in robots:
        p = located.fixes[f"red-{m + 1}"]
        assert math.hypot(p.x - x, p.y - y) < 0.1
    f = fuse.fuse([fuse.Sighting(1.0, 1.0, 350.0, 0.1, 0), fuse.Sighting(1.2, 1.0, 10.0, 0.1, 1)])
    assert abs(f.x - 1.1) < 1e-9 and min(f.heading, 360 - f.heading) < 1e-6 and f.sigma < 0.1


def test_the_marker_file_is_checked(tmp_path):
    ok = tmp_path / "m.toml"
    ok.write_text('marker_cm = 18\n[robots]\n10 = "red-1"\n11 = "blue-1"\n[floor]\n0 = [0, 0]\n1 = [5, 0]\n')
    b = binding.load_bindings(ok)
    assert b.robot_of(10) == "red-1" and b.floor[1] == (5.0, 0.0)
    assert binding.parse_bindings(__import__("tomllib").loads(b.to_toml())) == b
    bad = {
        '[robots]\n10 = "red-1"\n11 = "red-1"\n': "one marker per robot",
        '[robots]\n10 = "red-1"\n[floor]\n10 = [0, 0]\n': "both a robot's and a floor marker",
        '[robots]\n300 = "red-1"\n': "marker ids 0..249",
        '[floor]\n1 = "here"\n': "the cell",
        'marker_cm = 0\n': "marker_cm",
        '[robots\n': "not valid TOML",
    }
    for text, why in bad.items():
        ok.write_text(text)
        with pytest.raises(FieldError, match=why):
            binding.load_bindings(ok)


def test_intrinsics_from_checkerboard_views():
    board = np.full((7 * 40 + 80, 10 * 40 + 80), 255, np.uint8)
    for r in range(7):
        for c in range(10):
            if (r + c) % 2 == 0:
                board[40 + r * 40:80 + r * 40, 40 + c * 40:80 + c * 40] = 0
    views = []
    for k in range(5):
        src = np.float32([[0, 0], [board.shape[1], 0], [board.shape[1], board.shape[0]], [0, board.shape[0]]])
        dst = np.float32([[60 + 20 * k, 40], [560 - 10 * k, 60 + 8 * k], [600, 420 - 5 * k], [40 + 12 * k, 400]])
        views.append(cv2.warpPerspective(board, cv2.getPerspectiveTransform(src, dst), (640, 480), borderValue=255))
    k_, dist, rms = calibrate.calibrate_intrinsics(views)
    assert k_.shape == (3, 3) and rms < 1.0
    with pytest.raises(FieldError, match="3 or more views"):
        calibrate.calibrate_intrinsics(views[:2])


def test_cli_markers_calibrate_and_run_on_a_folder_of_frames(tmp_path):
    rc = subprocess.run([sys.executable, "-m", "robo_comp.cli", "camera", "markers", str(tmp_path / "sheet.png"),
                         "--ids", "0-3,200"], capture_output=True, text=True, timeout=60)
    assert rc.returncode == 0 and "5 markers" in rc.stdout
    assert cv2.imread(str(tmp_path / "sheet.png")) is not None
    cam = synth.cameras_for(W, H)[0]
    robots = _robots(4)
    b = binding.Bindings({m: f"red-{m + 1}" for m, *_ in robots}, FLOOR)
    (tmp_path / "markers.toml").write_text(b.to_toml())
    cv2.imwrite(str(tmp_path / "empty.png"), cam.render(WALLS, [], FLOOR))
    rc = subprocess.run([sys.executable, "-m", "robo_comp.cli", "camera", "calibrate", str(tmp_path / "empty.png"),
                         str(tmp_path / "cal.json"), "--markers", str(tmp_path / "markers.toml")],
                        capture_output=True, text=True, timeout=60)
    assert rc.returncode == 0, rc.stderr
    assert f"{len(FLOOR)} floor markers in view; reprojection error" in rc.stdout
    frames = tmp_path / "frames"
    frames.mkdir()
    for i in range(5):
        cv2.imwrite(str(frames / f"{i:03d}.png"), cam.render(WALLS, robots, FLOOR))
    url = f"tcp://127.0.0.1:{_free_port()}"
    ctx = zmq.Context.instance()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"fixes")
    sub.connect(url)
    proc = subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "camera", "run", "--markers",
                             str(tmp_path / "markers.toml"), "--pub", url, "--source", str(frames),
                             "--calibration", str(tmp_path / "cal.json")], stdout=subprocess.PIPE, text=True)
    try:
        got = []
        t_end = time.monotonic() + 30
        while not got and time.monotonic() < t_end:
            if sub.poll(500):
                got.append(P.unpack(sub.recv_multipart()[1]))
            elif proc.poll() is not None:  # the folder played before we subscribed: play it again
                proc = subprocess.Popen(proc.args, stdout=subprocess.PIPE, text=True)
        assert got, "no fixes published"
        fixes = {f["robot"]: f for f in got[0]["fixes"]}
        for m, x, y, _ in robots:
            f = fixes[f"red-{m + 1}"]
            assert math.hypot(f["x"] - x, f["y"] - y) < 0.1 and f["cameras"] == [0]
    finally:
        proc.kill()
        proc.wait()
        sub.close(0)
    bad = subprocess.run([sys.executable, "-m", "robo_comp.cli", "camera", "run", "--markers",
                          str(tmp_path / "markers.toml"), "--source", str(tmp_path / "nothing")],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "one --calibration per --source" in bad.stderr


def test_a_host_takes_fixes_for_its_own_robots_only(core):
    """A camera publishes a fix for a blue robot and one for a red robot: the red team's host
    moves its own robot and ignores the other (a team cannot claim another team's marker)."""
    url = f"tcp://127.0.0.1:{_free_port()}"
    create_keys(core.state, ["red", "blue"])
    ctx = zmq.Context.instance()
    pub = ctx.socket(zmq.PUB)
    open_server(pub, *load_secret(core.state / "keys" / "organiser.key_secret"))
    pub.bind(url)
    host = RobotHost(resolve_core(str(core.state)), core.host_token("red"), 1, positioning=url,
                     camera_key=core.state / "keys" / "organiser.key")
    th = threading.Thread(target=host.run, kwargs={"duration": 30}, daemon=True)
    th.start()
    try:
        red = core.client("red")
        wait_robots(red, 1)
        assert host.loc is not None and host.loc.external
        t_end = time.monotonic() + 10
        while host.camera_fixes == 0 and time.monotonic() < t_end:
            msg = {"t": time.time(), "seq": 0, "fixes": [
                {"robot": "blue-1", "x": 2.0, "y": 2.0, "heading": 0.0, "sigma": 0.05, "cameras": [0]},
                {"robot": "red-1", "x": 3.0, "y": 3.0, "heading": 90.0, "sigma": 0.05, "cameras": [0]},
                {"robot": "red-1", "x": "nonsense"}]}
            pub.send_multipart([b"fixes", P.pack(msg)])
            pub.send_multipart([b"fixes", b"\xc1 not msgpack"])
            time.sleep(0.1)
        assert host.camera_fixes >= 1
        assert "blue-1" not in host.loc.reckoners
    finally:
        host.stop()
        th.join(5)
        pub.close(0)


def test_robots_finish_goto_seen_only_through_synthetic_camera_frames(core, tmp_path):
    """Core, a robot host whose positions come only from the camera, and `robo-comp camera run
    --synthetic`: two overlapping synthetic cameras draw the host's arena, the camera finds the
    markers and the host corrects its dead reckoning with them; goTo tasks finish at their goals."""
    truth = f"tcp://127.0.0.1:{_free_port()}"
    fixes = f"tcp://127.0.0.1:{_free_port()}"
    b = binding.Bindings({10 + i: f"red-{i + 1}" for i in range(3)}, FLOOR)
    (tmp_path / "markers.toml").write_text(b.to_toml())
    create_keys(core.state, ["red", "blue"])  # the host beside the core pins STATE/keys/organiser.key
    host = start_robots(core.state, "red", 3, "--positioning", f"camera:{fixes}", "--truth-pub", truth)
    cam = subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "camera", "run", "--markers",
                            str(tmp_path / "markers.toml"), "--pub", fixes, "--synthetic", truth, "--cameras", "2",
                            "--fps", "10", "--key", str(core.state / "keys" / "organiser.key_secret")],
                           stderr=subprocess.PIPE, text=True)
    try:
        red = core.client("red")
        red.watch(True)
        rows = wait_robots(red, 3)
        walls = P.unpack_walls(red.arena())
        ys, xs = np.nonzero(~walls)
        open_cells = [(x, y) for x, y in zip(xs.tolist(), ys.tolist()) if not walls[y - 1:y + 2, x - 1:x + 2].any()]
        for r in rows[:2]:  # one after the other, so that they do not meet on the way
            here = red.monitor(r["tag"])
            others = [(o["x"], o["y"]) for o in red.robots() if o["tag"] != r["tag"]]
            goal = max((c for c in open_cells if all(abs(c[0] - ox) + abs(c[1] - oy) > 4 for ox, oy in others)),
                       key=lambda c: abs(c[0] - here["x"]) + abs(c[1] - here["y"]))
            tid = red.give(r["tag"], "goTo", list(goal))["task_id"]
            done = next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == tid, 60)
            assert done["data"]["ok"], done["data"]["status"]
            m = red.monitor(r["tag"])
            assert math.hypot(m["x"] - goal[0], m["y"] - goal[1]) < 0.5, (m["x"], m["y"], goal)
            assert m["sigma"] < 0.08, m["sigma"]  # with fixes; dead reckoning alone: ~0.15 after 25 cells
    finally:
        cam.kill()
        cam.wait()
        stop_all([host])
