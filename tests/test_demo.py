"""``robo-comp demo`` as a newcomer runs it: a real match that rescues victims, ends with a
winner, and leaves its state folder for ``robo-comp web --replay``, saying so; on a loaded machine
(a robot host slow to start) it waits and says what for; a host that dies is named at once, with
the end of its log."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from robo_comp.web.replay import Recording

#: Put on PYTHONPATH, this makes the robot host of team $HOST_TEAM slow to start (it sleeps
#: $HOST_DOES seconds first: what a loaded machine does to a Python process) or die ("exit").
HOST_TROUBLE = """
import os, sys, time
team = os.environ.get("HOST_TEAM")
if team and "robots" in sys.argv and any(a.endswith(f"hosts/{team}.token") for a in sys.argv):
    if os.environ["HOST_DOES"] == "exit":
        print("this host could not start (the test's stand-in for a crash)", flush=True)
        os._exit(3)
    time.sleep(float(os.environ["HOST_DOES"]))
"""


def troubled(tmp_path: Path, team: str, does: str) -> dict[str, str]:
    """The environment of a demo whose robot host of ``team`` is slow (``does``: seconds) or dies."""
    (tmp_path / "site").mkdir()
    (tmp_path / "site" / "sitecustomize.py").write_text(HOST_TROUBLE)
    return dict(os.environ, TMPDIR=str(tmp_path), HOST_TEAM=team, HOST_DOES=does,
                PYTHONPATH=os.pathsep.join(filter(None, [str(tmp_path / "site"), os.environ.get("PYTHONPATH")])))


def test_demo_finds_victims_and_leaves_a_replay(tmp_path: Path) -> None:
    """The demo on a "loaded machine": blue's host takes 7 s to start; the demo says what it waits
    for (it used to wait in silence), then plays the match."""
    env = troubled(tmp_path, "blue", "7")  # the demo's kept state folder goes in the test's folder
    p = subprocess.run([sys.executable, "-m", "robo_comp.cli", "demo", "--duration", "30"], capture_output=True,
                       text=True, timeout=300, env=env)
    out = p.stdout + p.stderr
    assert p.returncode == 0, out[-3000:]
    assert re.search(r"^demo: starting a core and two robot hosts; their logs are in \S+", out, re.M), out[:2000]
    assert re.search(r"^demo: waiting for the robots to register \(red \d/3, blue 0/3; load [\d.]+ on \d+ cores: "
                     r"Python starts slowly on a loaded machine; the hosts' logs: \S+/robots-\*\.log\)$", out, re.M), \
        out[:2000]
    assert len(re.findall(r"reported \w+ at \(\d+, \d+\) with \d+ pictures: confirmed", out)) >= 2, out[-3000:]
    scores = dict(re.findall(r"^\s+\d\. (\w+)\s+(-?[\d.]+) points", out, re.M))
    assert len(scores) == 2 and all(float(v) > 0 for v in scores.values()), out[-1500:]
    m = re.search(r"watch it again with: robo-comp web --replay (\S+)", out)
    assert m, out[-1500:]
    log = Path(m.group(1))
    assert log.is_file() and log.parent.parent == tmp_path
    assert (log.parent / "results.json").is_file()
    # the replay tells the story: the finds, and the victims revealed at the end
    view = Recording(log).build("public")
    assert '"kind":"find"' in view.story_json and '"found_by":["' in view.story_json


def test_a_robot_host_that_dies_is_named_at_once_with_its_log(tmp_path: Path) -> None:
    """It used to go unnoticed until the wait ran out (60 s), then blamed every log at once."""
    p = subprocess.run([sys.executable, "-m", "robo_comp.cli", "demo", "--duration", "5"], capture_output=True,
                       text=True, timeout=300, env=troubled(tmp_path, "blue", "exit"))
    out = p.stdout + p.stderr
    assert p.returncode == 1, out[-3000:]
    m = re.search(r"demo failed: the robot host of team blue exited with status 3 before its robots registered; "
                  r"the end of its log \((\S+/robots-blue\.log)\):\n    this host could not start", out)
    assert m and Path(m.group(1)).is_file(), out[-3000:]
    assert "Traceback" not in out, out[-3000:]
