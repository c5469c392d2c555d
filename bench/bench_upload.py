"""Upload → checked → available on the robot, end to end through the core (issue 4).

    .venv/bin/python bench/bench_upload.py [--robots 4] [--rounds 20]

Real processes over TCP on localhost: a core, one robot host of ``--robots`` robots, and this
process as the team's console. Each round uploads ``team_templates/extensions/square.py`` (a
new version each time) to every robot with :meth:`Client.upload` and times the request until
its reply, which comes once every robot's host has checked the module against the init
contract in the team's sandbox and the core has taken the robots' new task lists; the task is
then given at once to prove it is available. The first upload of a host also starts its
sandbox process (reported separately: *cold*).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from robo_comp.client import Client  # noqa: E402
from robo_comp.launch import start_core, start_robots, stop_all  # noqa: E402

SQUARE = (Path(__file__).resolve().parents[1] / "team_templates" / "extensions" / "square.py").read_text()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=4)
    ap.add_argument("--rounds", type=int, default=20)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        state = Path(tmp)
        core = start_core(state, "--teams", "red,blue", "--heartbeat", "1")
        host = start_robots(state, "red", a.robots)
        try:
            c = Client(str(state), (state / "teams" / "red.token").read_text().strip(), timeout=30)
            t_end = time.monotonic() + 30
            while sum(r["status"] == "connected" for r in c.robots()) < a.robots:
                assert time.monotonic() < t_end, "robots did not register"
                time.sleep(0.1)
            tags = [r["tag"] for r in c.robots()]
            times = []
            for i in range(a.rounds + 1):
                source = SQUARE.replace('"version": "1.0"', f'"version": "1.{i}"')
                t0 = time.perf_counter()
                out = c.upload(tags, "square.py", source)
                dt = (time.perf_counter() - t0) * 1000
                assert out["ok"], out
                c.give(tags[0], "square", [1])  # available now: the core accepts the task
                c.stop(tags[0])
                times.append(dt)
            cold, warm = times[0], sorted(times[1:])
            print(f"upload to {a.robots} robots -> checked -> available, cold (starts the sandbox): {cold:.1f} ms")
            print(f"same, warm (new version into the running sandbox), n={len(warm)}: "
                  f"median {statistics.median(warm):.1f} ms, max {warm[-1]:.1f} ms  (target < 300 ms)")
            c.close()
        finally:
            stop_all([host, core])
    return 0


if __name__ == "__main__":
    sys.exit(main())
