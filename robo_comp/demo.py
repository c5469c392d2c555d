"""``robo-comp demo``: a core and two teams of simulated robots on localhost, in one command.

Everything runs as real processes talking over real sockets: the core (the bundled ``demo_room``
scenario, with match phases), one robot host per team. The referee starts the match; two team
clients give tasks (now and queued); one robot of each team examines the area of a victim and
the team reports it with the pictures as evidence (the demo knows where the victims are: a
team's code has to search for them); one robot is stopped and given a new task; a cross-team
command is refused; a live summary prints every second; the referee finishes the match.

The state folder (event log, results, pictures) is kept and its path printed, with the command
that replays the match in a browser (``robo-comp web --replay STATE/events.log``).
"""
from __future__ import annotations

import json
import os
import random
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robo_comp.client import Client
from robo_comp.protocol import unpack_walls
from robo_comp.errors import RoboCompError
from robo_comp.launch import start_core, start_robots, stop_all
from robo_comp.world.scenario import bundled_scenario_path, load_scenario

#: The demo's scenario (bundled): a 24×16 room with three hidden victims.
SCENARIO = "demo_room"
#: Seconds the demo waits for the next robot to register (a loaded machine starts Python processes
#: slowly: each robot that registers starts the wait again, so a slow start is waited for, a stuck
#: one is not).
REGISTER_WITHIN = 60.0
#: While robots register, the demo says every this many seconds what it still waits for.
TELL_EVERY = 5.0


@dataclass
class Search:
    """A victim the demo sends a robot to: examine the area next to it, then report it."""

    team: str
    tag: int
    victim: dict[str, Any]
    at: tuple[int, int]
    task_id: int = -1
    reported: bool = False


def _free_cells(walls: Any) -> list[tuple[int, int]]:
    h, w = walls.shape
    return [(x, y) for y in range(h) for x in range(w) if not walls[y, x]]


def _start_web(state: Path, port: int, out: Any) -> Any:
    """The web gateway on the demo's core (``--web PORT``); prints the URL to open."""
    from robo_comp.launch import _spawn

    proc = _spawn(["web", "--core", str(state), "--port", str(port)], state / "web.log")
    t_end = time.monotonic() + 15
    while time.monotonic() < t_end and proc.poll() is None:
        text = (state / "web.log").read_text(errors="replace") if (state / "web.log").exists() else ""
        if "http://" in text:
            url = text.split("http://", 1)[1].split()[0]
            print(f"demo: watch the match in a browser: http://{url}", file=out)
            return proc
        time.sleep(0.1)
    log = (state / "web.log").read_text(errors="replace")[-500:] if (state / "web.log").exists() else ""
    print(f"demo: the web gateway did not start: {log}", file=out)
    return proc


def _start_camera(state: Path, teams: list[str], robots: int, out: Any) -> list[Any]:
    """The teams' hosts with positions from a camera process drawing synthetic frames of them."""
    import socket
    import subprocess

    from robo_comp.protocol.curve import create_keys
    from robo_comp.teams.tokens import ORGANISER
    from robo_comp.world.overhead.binding import Bindings
    from robo_comp.world.overhead.synth import floor_markers

    def port() -> int:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            return int(s.getsockname()[1])

    h, w = load_scenario(bundled_scenario_path(SCENARIO)).walls.shape
    bind = Bindings({10 + i * robots + k: f"{t}-{k + 1}" for i, t in enumerate(teams) for k in range(robots)},
                    floor_markers(w, h))
    (state / "markers.toml").write_text(bind.to_toml())
    # the camera speaks under the organiser's key, and the hosts (beside the core) pin its public half
    create_keys(state, teams)
    fixes = f"tcp://127.0.0.1:{port()}"
    truths = [f"tcp://127.0.0.1:{port()}" for _ in teams]
    procs = [start_robots(state, t, robots, "--positioning", f"camera:{fixes}", "--truth-pub", u,
                          "--scenario", str(bundled_scenario_path(SCENARIO)))
             for t, u in zip(teams, truths)]
    log = open(state / "camera.log", "wb")
    procs.append(subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "camera", "run", "--markers",
                                   str(state / "markers.toml"), "--pub", fixes, "--synthetic", ",".join(truths),
                                   "--cameras", "2", "--key", str(state / "keys" / f"{ORGANISER}.key_secret")],
                                  stdout=log, stderr=subprocess.STDOUT))
    print("demo: robot positions come from two synthetic overhead cameras (robo-comp camera run)", file=out)
    return procs


def _hosts_without_os_layer_if_needed(out: Any) -> None:
    """The demo uploads no team code: where the sandbox's OS layer cannot start (a laptop without
    bubblewrap), its robot hosts run without it, and the demo says so, rather than stop as
    ``robo-comp robots`` does there."""
    from robo_comp.errors import UnavailableError
    from robo_comp.sandbox import oswall

    if not oswall.enabled():
        return
    try:
        oswall.check(oswall.package_root())
    except UnavailableError as e:
        os.environ[oswall.ENV] = "off"  # for the hosts this process starts
        print(f"demo: the sandbox's OS layer cannot start here ({e.details.get('why', e.message)}); the demo's "
              "robot hosts run without it (the demo uploads no team code)", file=out)


def _tail(path: Path, lines: int = 5) -> str:
    """The last lines of a log file, indented (or a sentence when there is none)."""
    try:
        text = path.read_text(errors="replace").strip().splitlines()[-lines:]
    except OSError:
        return "    (no log was written)"
    return "\n".join(f"    {ln}" for ln in text) or "    (the log is empty)"


def _load() -> str:
    """``; load 7.9 on 2 cores`` (the 1-minute load average), or "" where the system does not say."""
    try:
        return f"; load {os.getloadavg()[0]:.1f} on {os.cpu_count() or '?'} cores"
    except OSError:
        return ""


def wait_for_robots(clients: dict[str, Client], robots: int, hosts: dict[str, Any], state: Path, out: Any,
                    quiet_for: float = REGISTER_WITHIN, tell_every: float = TELL_EVERY) -> None:
    """Wait until every team has ``robots`` robots registered. Every ``tell_every`` seconds it says
    how many have and how loaded the machine is; a host that exits fails the demo at once with the
    end of its log; it gives up only after ``quiet_for`` seconds in which no robot registered, and
    then says which team is short, the load, and where each log is (``RuntimeError``)."""
    def counts() -> dict[str, int]:
        return {t: len(c.robots()) for t, c in clients.items()}

    logs = {t: state / f"robots-{t}.log" for t in clients}
    seen = counts()
    last_progress = next_tell = time.monotonic()
    next_tell += tell_every
    while any(n < robots for n in seen.values()):
        for team, host in hosts.items():
            if team in logs and host.poll() is not None:
                raise RuntimeError(f"the robot host of team {team} exited with status {host.returncode} before its "
                                   f"robots registered; the end of its log ({logs[team]}):\n{_tail(logs[team])}")
        now = time.monotonic()
        have = ", ".join(f"{t} {n}/{robots}" for t, n in seen.items())
        if now >= next_tell:
            print(f"demo: waiting for the robots to register ({have}{_load()}: Python starts slowly on a "
                  f"loaded machine; the hosts' logs: {state}/robots-*.log)", file=out, flush=True)
            next_tell = now + tell_every
        if now - last_progress > quiet_for:
            short = ", ".join(f"team {t} has {n} of {robots}" for t, n in seen.items() if n < robots)
            raise RuntimeError(
                f"no robot registered for {quiet_for:.0f} s ({short}{_load()}); the logs: "
                + ", ".join(str(p) for p in logs.values()) + f", {state / 'core.log'}; the end of each host's log:\n"
                + "\n".join(f"  {t}:\n{_tail(p)}" for t, p in logs.items()))
        time.sleep(0.1)
        now_seen = counts()
        if now_seen != seen:
            seen, last_progress = now_seen, time.monotonic()


def run_demo(duration: float = 20.0, robots: int = 3, out: Any = None, web: int | None = None,
             camera: bool = False) -> int:
    """Run the demo match; prints a live summary and a final table; returns 0 on success.
    ``web``: also serve the match on a page at this port (0: a free one). ``camera``: the robots'
    positions come only from synthetic overhead-camera frames (docs/positioning.md)."""
    out = out or sys.stdout
    rng = random.Random(7)
    scenario = bundled_scenario_path(SCENARIO)
    state = Path(tempfile.mkdtemp(prefix="robo-comp-demo-"))  # kept: the match can be replayed
    procs: list[Any] = []
    _hosts_without_os_layer_if_needed(out)
    try:
        # the organiser's hosts run `robots` robots a team (the scenario gives each team 2)
        print(f"demo: starting a core and two robot hosts; their logs are in {state}", file=out)
        procs.append(start_core(state, "--scenario", str(scenario), "--robots", str(robots), wait=REGISTER_WITHIN))
        teams = json.loads((state / "core.json").read_text())["teams"][:2]
        if web is not None:
            procs.append(_start_web(state, web, out))
        if camera:
            hosts = _start_camera(state, teams, robots, out)
        else:  # organiser's hosts: their cameras show the hidden victims
            hosts = [start_robots(state, t, robots, "--scenario", str(scenario)) for t in teams]
        procs += hosts
        clients = {t: Client(str(state), (state / "teams" / f"{t}.token").read_text().strip(),
                             client="demo") for t in teams}
        referee = Client(str(state), (state / "referee.token").read_text().strip(), client="demo-referee")
        for c in clients.values():
            c.watch(True)
        wait_for_robots(clients, robots, dict(zip(teams, hosts)), state, out)
        free = _free_cells(unpack_walls(next(iter(clients.values())).arena()))
        print(f"demo: core and {len(teams)} teams of {robots} robots up; "
              f"arena {len(free)} free cells", file=out)
        referee.request("match", action="start")
        print("demo: the referee started the match", file=out)
        searches = _plan_searches(clients, load_scenario(scenario).victims, free)
        _give_opening_tasks(clients, free, rng, out, searches)
        counts = _watch(clients, free, rng, duration, out, searches)
        referee.request("match", action="finish")
        print("demo: the referee finished the match", file=out)
        _final_table(clients, counts, out)
        _scores(referee, out)
        referee.close()
        for c in clients.values():
            c.close()
    except (RoboCompError, RuntimeError) as e:
        print(f"demo failed: {e}", file=out)
        print(f"demo: the logs are in {state}", file=out)
        return 1
    finally:
        stop_all(procs)
    print(f"demo: the match's state folder is kept in {state} (event log, results, pictures); "
          f"watch it again with: robo-comp web --replay {state / 'events.log'}", file=out)
    return 0


def _plan_searches(clients: dict[str, Client], victims: list[Any], free: list[tuple[int, int]]) -> list[Search]:
    """One victim for a robot of each team in turn (the first robots of each team): examine from
    a free cell next to the victim."""
    free_set = set(free)
    out: list[Search] = []
    rows = {t: c.robots() for t, c in clients.items()}
    teams = list(clients)
    for i, v in enumerate(victims):
        team = teams[i % len(teams)]
        k = i // len(teams)
        if k >= len(rows[team]) - 1:  # the last robot of each team is the one the demo stops
            continue
        spots = [(v.x + dx, v.y + dy) for dx, dy in ((0, 1), (0, -1), (1, 0), (-1, 0))]
        at = next((p for p in spots if p in free_set), None)
        if at is not None:
            out.append(Search(team, rows[team][k]["tag"], v.to_dict(), at))
    return out


def _give_opening_tasks(clients: dict[str, Client], free: list[tuple[int, int]], rng: random.Random,
                        out: Any, searches: list[Search]) -> None:
    teams = list(clients)
    for s in searches:
        s.task_id = clients[s.team].give(s.tag, "examineArea", list(s.at))["task_id"]
        print(f"demo: team {s.team} sends robot {s.tag} to examine the area at {s.at}", file=out)
    searching = {s.tag for s in searches}
    for team, c in clients.items():
        for i, r in enumerate(c.robots()):
            tag = r["tag"]
            if tag in searching:
                continue
            x, y = rng.choice(free)
            if i % 3 == 0:
                c.give(tag, "goTo", [x, y])
            elif i % 3 == 1:
                c.give(tag, "followPath", [[list(rng.choice(free)), [x, y]]])
            else:
                c.give(tag, "examineArea", [x, y])
            c.give(tag, "goTo", list(rng.choice(free)), queue=True)
        print(f"demo: team {team} gave each robot a task now and one queued", file=out)
    # Ownership: the first team may not command the second team's robots.
    other = clients[teams[1]].robots()[0]["tag"]
    try:
        clients[teams[0]].give(other, "goTo", [1, 1])
    except RoboCompError as e:
        print(f"demo: team {teams[0]} tried robot {other} of team {teams[1]} -> refused: {e.code}: {e.message}",
              file=out)


def _report(c: Client, s: Search, result: Any, out: Any) -> None:
    """The team reports the victim its robot examined, citing the pictures it took."""
    pictures = result.get("pictures", []) if isinstance(result, dict) else []
    v = s.victim
    try:
        answer = c.request("find", tag=s.tag, x=v["x"], y=v["y"], kind=v.get("kind", ""), evidence=pictures)
        print(f"demo: team {s.team} reported {v.get('kind')} at ({v['x']}, {v['y']}) with {len(pictures)} "
              f"pictures: {answer['state']} ({answer.get('message', '')})", file=out)
    except RoboCompError as e:
        print(f"demo: team {s.team}'s report was refused: {e.code}: {e.message}", file=out)
    s.reported = True


def _scores(referee: Client, out: Any) -> None:
    print("\nscores", file=out)
    for row in referee.score().get("teams", []):
        print(f"  {row.get('rank')}. {row['team']:<8} {row['score']:>6g} points, {row['victims']} victim{'' if row['victims'] == 1 else 's'}", file=out)


def _watch(clients: dict[str, Client], free: list[tuple[int, int]], rng: random.Random, duration: float,
           out: Any, searches: list[Search] | None = None) -> dict[str, int]:
    by_task = {(s.team, s.task_id): s for s in searches or []}
    counts = {"task.done": 0, "robot.stopped": 0, "robot.lost": 0}
    t0 = time.monotonic()
    next_print = t0 + 1
    stopped = False
    while time.monotonic() - t0 < duration:
        for team, c in clients.items():
            ev = c.next_event(0.05)
            while ev is not None:
                topic, data = ev["topic"], ev["data"]
                if topic in counts:
                    counts[topic] += 1
                s = by_task.get((team, data.get("task_id"))) if topic == "task.done" else None
                if s is not None and not s.reported:
                    if data.get("ok"):
                        _report(c, s, data.get("result"), out)
                    else:
                        print(f"demo: robot {s.tag} could not examine {s.at}: {data.get('status')}", file=out)
                        s.reported = True
                if topic == "task.done" and data.get("state") == "done":
                    # keep robots busy: a new queued task whenever one finishes
                    c.give(data["tag"], "goTo", list(rng.choice(free)), queue=True)
                ev = c.next_event(0)
        if not stopped and time.monotonic() - t0 > duration / 3:
            team, c = next(iter(clients.items()))
            tag = c.robots()[-1]["tag"]  # (the first robots are searching)
            res = c.stop(tag)
            print(f"demo: STOP robot {tag}: halted in {res['ms']:.1f} ms, cancelled {res['cancelled']}",
                  file=out)
            c.give(tag, "goTo", list(rng.choice(free)))
            print(f"demo: robot {tag} took a new task after the stop", file=out)
            stopped = True
        if time.monotonic() >= next_print:
            next_print += 1
            parts = []
            for team, c in clients.items():
                rows = c.robots()
                moving = sum(r["moving"] for r in rows)
                parts.append(f"{team}: {moving}/{len(rows)} moving")
            print(f"[{time.monotonic() - t0:5.1f}s] {'  '.join(parts)}  tasks done: {counts['task.done']}",
                  file=out, flush=True)
    return counts


def _final_table(clients: dict[str, Client], counts: dict[str, int], out: Any) -> None:
    print("\nfinal table", file=out)
    print(f"{'team':<8} {'tag':>5} {'status':<10} {'pos':>13} {'done':>5} {'ok':>4}  current", file=out)
    for team, c in clients.items():
        for r in c.robots():
            t = c.tasks(r["tag"])
            done = [d for d in t["done"] if d["state"] == "done"]
            ok = sum(1 for d in done if d["ok"])
            cur = f"{t['current']['name']}#{t['current']['task_id']}" if t["current"] else "-"
            print(f"{team:<8} {r['tag']:>5} {r['status']:<10} ({r['x']:5.1f},{r['y']:5.1f}) "
                  f"{len(done):>5} {ok:>4}  {cur}", file=out)
    print(f"events seen: {counts}", file=out)
