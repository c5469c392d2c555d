"""The newcomer's papercuts of issue 29, each seen from the command line as a user meets it: real
``robo-comp`` processes on a real core, their output and exit status read as a person reads them."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import wait_robots
from robo_comp.testing import start_match

RC = [sys.executable, "-m", "robo_comp.cli"]


def run(*args: str, timeout: float = 60, **kw) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*RC, *args], capture_output=True, text=True, timeout=timeout, **kw)


@pytest.fixture(scope="module")
def match(tmp_path_factory: pytest.TempPathFactory):
    state = tmp_path_factory.mktemp("papercuts") / "state"
    m = start_match(state, "demo_room", teams=["red", "blue"])
    try:
        m.robots("red", 1, speed=8)
        tag = wait_robots(m.client("red"), 1)[0]["tag"]
        yield m, tag
    finally:
        m.close()


def ctl(m, *args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return run("ctl", "--core", str(m.state), "--token-file", str(m.token_file("red")), *args, timeout=timeout)


def test_give_takes_plain_values_and_refuses_a_wall(match) -> None:
    m, tag = match
    p = ctl(m, "give", str(tag), "goTo", "3", "4")
    assert p.returncode == 0 and "goTo [3, 4]" in p.stdout, p.stdout + p.stderr
    assert "usage:" not in p.stderr
    p = ctl(m, "give", str(tag), "goTo", "[0, 0]")  # the room's corner is wall
    assert p.returncode == 1 and "(0, 0) is a wall" in p.stderr and "not given" in p.stderr, p.stdout + p.stderr
    p = ctl(m, "give", str(tag), "goTo", "40", "4")
    assert p.returncode == 1 and "outside the 24×16 arena" in p.stderr, p.stderr
    p = ctl(m, "give", str(tag), "followPath", "[[3, 4], [0, 0]]")
    assert p.returncode == 1 and "(0, 0) is a wall" in p.stderr, p.stderr
    p = ctl(m, "give", str(tag), "followPath", "[[3, 4], [3, 5]]", "--queue")
    assert p.returncode == 0 and "followPath [[[3, 4], [3, 5]]]" in p.stdout, p.stdout + p.stderr


def test_monitor_reads_like_text(match) -> None:
    m, tag = match
    p = ctl(m, "monitor", str(tag))
    assert p.returncode == 0, p.stderr
    out = p.stdout
    assert "None" not in out and "{'" not in out and "[{" not in out, out
    assert not re.search(r"\b1\d{9}(\.\d+)?\b", out), out  # no epoch seconds
    assert re.search(r"registered at: \d\d:\d\d:\d\d \([\d.]+ s ago\)", out), out
    assert "can run: goTo(x, y), followPath(points), examineArea(x, y)" in out, out


def test_robots_into_head_ends_quietly(match) -> None:
    m, _ = match
    cmd = " ".join([*RC, "ctl", "--core", str(m.state), "--token-file", str(m.token_file("red")), "robots"])
    p = subprocess.run(f"{cmd} | head -c 10", shell=True, capture_output=True, text=True, timeout=60)
    assert "Traceback" not in p.stderr and "BrokenPipe" not in p.stderr, p.stderr


def test_events_filter_by_topic_and_each_picture_once(match) -> None:
    """The core pushes each picture once: to the team with what it shows, to the public feed
    without (``ctl events`` prints what it is sent, it does not de-duplicate)."""
    m, tag = match
    base = [*RC, "ctl", "--core", str(m.state), "--token-file", str(m.token_file("red")), "--json", "events",
            "--topic", "picture", "--timeout", "40"]
    own = subprocess.Popen([*base, "--count", "6"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    pub = subprocess.Popen([*base, "--count", "6", "--public"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           text=True)
    try:
        import time

        time.sleep(1.5)  # the events commands are watching before the task starts
        assert ctl(m, "give", str(tag), "examineArea", "9", "6").returncode == 0
        out, err = own.communicate(timeout=60)
        pout, perr = pub.communicate(timeout=60)
    finally:
        for p in (own, pub):
            if p.poll() is None:
                p.kill()
    rows = [json.loads(line) for line in out.splitlines() if line.strip()]
    assert rows and {r["topic"] for r in rows} == {"picture"}, out + err
    ids = [r["data"]["id"] for r in rows]
    assert len(ids) == len(set(ids)) == 4, ids  # examineArea's four pictures, each once
    assert all("victims" in r["data"] for r in rows), rows  # the team's copy says what it shows
    prow = [json.loads(line) for line in pout.splitlines() if line.strip()]
    assert [r["data"]["id"] for r in prow] == ids, pout + perr
    assert not any("victims" in r["data"] or "sha256" in r["data"] for r in prow), prow


def test_core_takes_a_bundled_scenario_name(tmp_path: Path) -> None:
    p = subprocess.Popen([*RC, "core", "--state", str(tmp_path / "s"), "--port", "0", "--scenario", "demo_room"],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        line = p.stdout.readline() if p.stdout else ""
        assert "serving 'Demo room'" in line, line
        # a second core on the same state folder is refused with a sentence, and touches nothing
        before = sorted(x.name for x in (tmp_path / "s").iterdir())
        q = run("core", "--state", str(tmp_path / "s"), "--port", "0")
        assert q.returncode == 2 and "already serving" in q.stderr and "Traceback" not in q.stderr, q.stderr
        assert sorted(x.name for x in (tmp_path / "s").iterdir()) == before
        # a port in use: a sentence, and no half-made state folder
        port = json.loads((tmp_path / "s" / "core.json").read_text())["router"].rsplit(":", 1)[1]
        q = run("core", "--state", str(tmp_path / "other"), "--port", port)
        assert q.returncode == 2 and "port" in q.stderr and "Traceback" not in q.stderr, q.stderr
        assert not (tmp_path / "other").exists()
    finally:
        p.terminate()
        p.wait(10)
    q = run("core", "--state", str(tmp_path / "t"), "--scenario", "demo_rom")
    assert q.returncode == 2 and "no bundled scenario called 'demo_rom'" in q.stderr and "Traceback" not in q.stderr
    assert not (tmp_path / "t").exists()


def test_web_prints_no_pygame_banner(tmp_path: Path) -> None:
    """``robo-comp web`` prints its URL, not pygame's greeting (the map is drawn with pygame's colours)."""
    import threading

    from test_web import write_log

    log = tmp_path / "m" / "events.log"
    write_log(log, seconds=5)
    p = subprocess.Popen([*RC, "web", "--replay", str(log), "--port", "0"], stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []

    def read() -> None:
        for line in p.stdout:  # type: ignore[union-attr]
            lines.append(line)

    t = threading.Thread(target=read, daemon=True)
    t.start()
    try:
        import time

        t_end = time.monotonic() + 30
        while not any("http://" in x for x in lines) and time.monotonic() < t_end:
            time.sleep(0.1)
        import urllib.request

        url = next(x for x in lines if "http://" in x).split("http://", 1)[1].split()[0]
        urllib.request.urlopen(f"http://{url}", timeout=10).read()  # the public view (and its map) is built
    finally:
        p.terminate()
        p.wait(10)
        t.join(5)
    text = "".join(lines)
    assert "serving the replay" in text and "hello from the pygame" not in text.lower(), text


def test_a_finished_match_has_no_time_left() -> None:
    from robo_comp.tui.widgets.score import clock_text

    assert clock_text("finished", 194, 106) == "03:14 played"
    assert clock_text("running", 194, 106) == "01:46 left"
    assert clock_text("running", 194, None) == "03:14 elapsed"


def test_an_import_inside_a_function_is_refused_at_upload(match, tmp_path: Path) -> None:
    """``import os`` inside a task passed the upload check and failed only when the task ran in
    the match; the upload check now reads every import (a real upload to a real robot's sandbox)."""
    m, tag = match
    mod = tmp_path / "sneaky.py"
    mod.write_text('MANIFEST = {"name": "sneaky", "version": "1.0", "kind": "extension",\n'
                   '            "tasks": {"peek": {"description": "x", "args": []}}}\n\n\n'
                   "def peek(robot):\n"
                   "    import os\n"
                   "    return os.listdir('/')\n")
    p = ctl(m, "upload", str(tag), str(mod), timeout=120)
    said = p.stdout + p.stderr
    assert p.returncode == 1 and "sneaky.py:6" in said and "'os' is not allowed" in said, said
    ok = tmp_path / "fine.py"
    ok.write_text('MANIFEST = {"name": "fine", "version": "1.0", "kind": "extension",\n'
                  '            "tasks": {"root": {"description": "x", "args": []}}}\n\n\n'
                  "def root(robot):\n"
                  "    import math\n"
                  "    return math.sqrt(4)\n")
    p = ctl(m, "upload", str(tag), str(ok), timeout=120)
    assert p.returncode == 0 and "ok" in p.stdout, p.stdout + p.stderr


def test_scores_png_draws_each_team_in_its_own_colour(tmp_path: Path) -> None:
    """The plot coloured teams by rank (blue, leading, drawn red) and had no title or axes."""
    import os

    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    import pygame

    from robo_comp.scoring.results import write_results

    scores = {"phase": "finished", "elapsed": 60.0, "teams": [
        {"rank": 1, "team": "blue", "score": 20, "victims": 1, "penalties": 0, "disqualified": False},
        {"rank": 2, "team": "red", "score": -5, "victims": 0, "penalties": 5, "disqualified": False}]}
    lines = [{"team": "blue", "points": 20, "t": 10.0}, {"team": "red", "points": -5, "t": 30.0}]
    write_results(tmp_path, scores, lines, [], {"red": (230, 20, 20), "blue": (20, 60, 230)})
    img = pygame.image.load(str(tmp_path / "scores.png"))
    px = pygame.surfarray.array3d(img)  # [x, y, rgb]

    def count(rgb: tuple[int, int, int]) -> int:
        return int(((abs(px.astype(int) - rgb)).sum(axis=2) <= 6).sum())

    assert count((20, 60, 230)) > 200 and count((230, 20, 20)) > 200  # both lines, each in its colour
    w, h = img.get_size()
    title_band = px[w // 4: 3 * w // 4, 5:35]
    assert (title_band.sum(axis=2) < 200).sum() > 50  # a title in dark ink above the plot
    axis_labels = px[:, h - 25:h]
    assert (axis_labels.sum(axis=2) < 200).sum() > 50  # "match time (s)" below it


def test_robot_host_says_when_its_robots_register_and_when_the_core_is_back(tmp_path: Path) -> None:
    import time

    from conftest import wait_for
    from robo_comp.launch import start_core

    state = tmp_path / "state"
    m = start_match(state, "demo_room", teams=["red", "blue"])
    try:
        m.robots("red", 2)
        log = state / "robots-red.log"
        wait_for(lambda: "registered" in m.log_tail("robots-red.log"), 30, "the host to say its robots registered")
        assert re.search(r"robots: team red: 2 robot\(s\) registered with the core at \S+; tags \d+, \d+",
                         log.read_text()), log.read_text()
        m.proc.terminate()
        m.proc.wait(10)
        time.sleep(0.5)
        m.proc = start_core(state, "--scenario", str(m.scenario), "--teams", "red,blue", "--practice")
        wait_for(lambda: "again" in m.log_tail("robots-red.log"), 60, "the host to say the core is back")
        assert re.search(r"registered again \(reconnect \d+: the core is back\)", log.read_text()), log.read_text()
    finally:
        m.close()
