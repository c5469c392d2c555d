"""``robo-comp ctl``: a scriptable console for teams and the referee (text or ``--json``)."""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from robo_comp.client import Client, add_connection_args, read_token, recv_event, resolve_core
from robo_comp.errors import RoboCompError


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``ctl`` subcommand and its own subcommands."""
    p = sub.add_parser("ctl", help="list, monitor, task and stop robots from scripts",
                       description="Talk to a running core as a team or the referee. "
                                   "Exit status 1 and a clear message when the core refuses.")
    add_connection_args(p)
    p.add_argument("--json", action="store_true", help="print replies as JSON")
    cmds = p.add_subparsers(dest="cmd", required=True, metavar="COMMAND")
    cmds.add_parser("robots", help="list your robots (all robots for the referee)")
    for name, text in (("monitor", "all monitor data of a robot"), ("tasks", "a robot's tasks"),
                       ("stop", "halt a robot at once (it stays usable)")):
        c = cmds.add_parser(name, help=text)
        c.add_argument("tag", type=int)
    g = cmds.add_parser("give", help="give a task now (interrupting) or --queue it",
                        description="Examples: give 101 goTo 3 4; give 101 goTo '[3, 4]'; "
                                    "give 101 followPath '[[3, 4], [5, 6]]'. A cell in a wall or outside the "
                                    "arena is refused before the task is given.")
    g.add_argument("tag", type=int)
    g.add_argument("task", help="task name as the robot advertises it (see 'tasks TAG')")
    g.add_argument("args", nargs="*", default=[],
                   help="the task's arguments: each a value (3 4), or all of them as one JSON list ('[3, 4]')")
    g.add_argument("--queue", action="store_true", help="queue the task instead of interrupting")
    u = cmds.add_parser("upload", help="upload an extension or code module to robots",
                        description="Example: upload 101,102 square.py. The module is checked on each robot "
                                    "(docs/sandbox.md); a refusal names the file, line and rule.")
    u.add_argument("tags", type=_tag_list, help="robot tag, or several separated by commas")
    u.add_argument("file", help="the module (.py)")
    u.add_argument("--run", action="store_true", help="run the module's first task now (code that runs now)")
    x = cmds.add_parser("extensions", help="the modules uploaded to a robot")
    x.add_argument("tag", type=int)
    un = cmds.add_parser("unload", help="take an uploaded module away from robots")
    un.add_argument("tags", type=_tag_list, help="robot tag, or several separated by commas")
    un.add_argument("name", help="the module's MANIFEST name")
    sr = cmds.add_parser("sandbox-reset", help="referee: restart the team-code sandbox of robots now",
                         description="A sandbox whose code hit its limits too often rests (60 s, doubling) "
                                     "and restarts by itself; this restarts it at once.")
    sr.add_argument("tags", type=_tag_list, help="robot tag, or several separated by commas")
    cmds.add_parser("hosts", help="referee: the organiser's robot hosts and the robots each holds")
    ho = cmds.add_parser("handover", help="referee: hand robots to the next robot host that registers them",
                         description="Each robot is halted and let go by the host that holds it; the next host "
                                     "that registers it (with its robot id) runs it. For a host that hangs, or "
                                     "robots moving to a spare host.")
    ho.add_argument("tags", type=_tag_list, help="robot tag, or several separated by commas")
    m = cmds.add_parser("match", help="referee: start, pause, resume, finish or extend the match; "
                                      "or set the outage rule",
                        description="'outage --rule pause|count' chooses what a core outage (a crash, a restart) "
                                    "does to the running match clock: pause (the default: it stands still while "
                                    "no core runs) or count (the outage is match time).")
    m.add_argument("action", choices=("start", "pause", "resume", "finish", "extend", "outage"))
    m.add_argument("--seconds", type=float, help="for extend: seconds to add")
    m.add_argument("--rule", choices=("pause", "count"), help="for outage: the rule")
    tw = cmds.add_parser("teamwork", help="a lost robot's tasks to its teammates: on, off, or show the setting",
                         description="When one of your robots is lost (its host went silent) or leaves, its running "
                                     "and queued tasks are offered to your team (the task.offered event). With "
                                     "'teamwork on' each of them moves at once to the nearest idle teammate that "
                                     "advertises the task (none idle: the one with the least work). The referee "
                                     "names the team with --team.")
    tw.add_argument("setting", nargs="?", choices=("on", "off"), help="turn reallocation on or off (none: show it)")
    tw.add_argument("--team", help="referee: the team")
    cmds.add_parser("score", help="the scoreboard, phase and clock")
    cmds.add_parser("recovery", help="referee: what the core recovered from its event log when it started "
                                     "(events, damage and the events it cost, how the clock was set)")
    e = cmds.add_parser("events", help="print events as they happen")
    e.add_argument("--count", type=int, default=0, help="stop after N events (0 = never)")
    e.add_argument("--timeout", type=float, default=0.0, help="stop after S seconds (0 = never)")
    e.add_argument("--public", action="store_true", help="read the public wall feed instead of your own events")
    e.add_argument("--topic", action="append", default=[], metavar="PREFIX",
                   help="only topics starting with PREFIX (repeatable), e.g. --topic find --topic score")
    e.add_argument("--skip", action="append", default=[], metavar="PREFIX",
                   help="leave out topics starting with PREFIX (repeatable), e.g. --skip robot.positions")
    p.set_defaults(func=run)


def _tag_list(text: str) -> list[int]:
    """``101`` or ``101,102``: robot tags (an argparse type: anything else is a usage error)."""
    try:
        tags = [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"tags must be numbers separated by commas, got {text!r}") from None
    if not tags:
        raise argparse.ArgumentTypeError("give at least one robot tag")
    return tags


def _print_robots(rows: list[dict[str, Any]]) -> None:
    print(f"{'tag':>5} {'team':<8} {'status':<10} {'x':>7} {'y':>7} {'head':>5}  {'task':<22} queue")
    for r in rows:
        task = r["task"]
        label = f"{task['name']}#{task['task_id']}" if task else "-"
        print(f"{r['tag']:>5} {r['team']:<8} {r['status']:<10} {r['x']:>7.2f} {r['y']:>7.2f} "
              f"{r['heading']:>5.0f}  {label:<22} {r['queue']}")


def _print_hosts(rows: list[dict[str, Any]]) -> None:
    if not rows:
        print("no robot host is connected")
    for h in rows:
        since = time.strftime("%H:%M:%S", time.localtime(h["opened"]))
        print(f"host {h['host']}  team {h['team']}  since {since}  heard {h['silent']:.1f} s ago  "
              f"robots: {', '.join(f'{t} ({rid})' for t, rid in zip(h['tags'], h['robots'])) or '-'}")


def _when(v: Any) -> str:
    """An epoch time as the clock time and how long ago."""
    if not isinstance(v, (int, float)):
        return "-"
    ago = time.time() - float(v)
    return time.strftime("%H:%M:%S", time.localtime(float(v))) + (f" ({ago:.1f} s ago)" if ago >= 0 else "")


def _task_line(d: dict[str, Any]) -> str:
    args = d.get("args")
    text = f"{d.get('name')}#{d.get('task_id')} {json.dumps(args) if args is not None else ''}".rstrip()
    if "ok" in d and d.get("state") == "done":
        text += f"  {'ok' if d['ok'] else 'FAILED'}" + (f": {d['status']}" if d.get("status") else "")
    elif d.get("state"):
        text += f"  {d['state']}"
    return text


def _print_monitor(m: dict[str, Any]) -> None:
    """Monitor data for people: no None, no epoch seconds, no Python dict lists."""
    def row(k: str, v: Any) -> None:
        print(f"{k:>14}: {v}")

    for k, v in m.items():
        if k in ("advertised", "queued", "done", "sensors", "task") or k.endswith("_at") or k == "last_report":
            continue
        row(k, "-" if v is None else (f"{v:.2f}" if isinstance(v, float) else v))
    task = m.get("task")
    row("task", _task_line(task) if isinstance(task, dict) else (task or "-"))
    sensors = m.get("sensors")
    if isinstance(sensors, dict):
        parts = []
        for k, v in sensors.items():
            if k == "time":
                continue
            parts.append(f"{k} {'-' if v is None else (f'{v:g}' if isinstance(v, (int, float)) and not isinstance(v, bool) else v)}")
        row("sensors", ", ".join(parts) + ("  (ranges in cm; - = nothing in range)" if parts else ""))
    for k, v in m.items():
        if k.endswith("_at") or k == "last_report":
            row(k.replace("_", " "), _when(v))
    adv = m.get("advertised")
    if isinstance(adv, list):
        row("can run", ", ".join(f"{s.get('name')}({', '.join(a.get('name', '?') for a in s.get('args') or [])})"
                                 for s in adv if isinstance(s, dict)) or "-")
    for k in ("queued", "done"):
        items = m.get(k)
        if isinstance(items, list):
            row(k, "-" if not items else _task_line(items[0]))
            for d in items[1:]:
                print(" " * 16 + _task_line(d))


def _print_tasks(t: dict[str, Any]) -> None:
    print(f"robot {t['tag']} can run:")
    for s in t["advertised"]:
        args = ", ".join(f"{a['name']}: {a['type']}" for a in s["args"])
        print(f"  {s['name']}({args})  {s['description']}")
    cur = t["current"]
    print("current:", f"{cur['name']}#{cur['task_id']} {cur['args']}" if cur else "-")
    for q in t["queued"]:
        print(f"queued:  {q['name']}#{q['task_id']} {q['args']}")
    for d in t["done"][-10:]:
        print(f"done:    {d['name']}#{d['task_id']} ok={d['ok']} {d['status']}")


def run(args: argparse.Namespace) -> int:
    """Run one ``ctl`` command; 0 on success, 1 when refused, 2 on bad usage."""
    try:
        token = read_token(args.token, args.token_file)
        resolve_core(args.core)  # a clear message now for a wrong --core
    except RoboCompError as e:
        print(f"error: {e.message}", file=sys.stderr)
        return 2
    try:
        timeout = 30.0 if args.cmd in ("upload", "unload", "extensions", "sandbox-reset") else 5.0  # a sandbox may start first
        with Client(args.core, token, client="ctl", timeout=timeout, curve_cert=args.curve_cert,
                    core_key=args.core_key) as c:
            return _run(c, args)
    except RoboCompError as e:
        print(f"error {e.code}: {e.message}", file=sys.stderr)
        return 1


def _run(c: Client, args: argparse.Namespace) -> int:
    out: Any
    if args.cmd == "robots":
        out = c.robots()
        if not args.json:
            _print_robots(out)
    elif args.cmd == "monitor":
        out = c.monitor(args.tag)
        if not args.json:
            _print_monitor(out)
    elif args.cmd == "tasks":
        out = c.tasks(args.tag)
        if not args.json:
            _print_tasks(out)
    elif args.cmd == "hosts":
        out = c.request("hosts")["hosts"]
        if not args.json:
            _print_hosts(out)
    elif args.cmd == "handover":
        out = c.request("handover", tags=args.tags)
        if not args.json:
            print(f"handed over: {', '.join(map(str, out['released']))} (the next host that registers them runs them)")
    elif args.cmd == "give":
        task_args = _task_args(args.args)
        if task_args is None:
            print(f"error: arguments must be values (goTo 3 4) or one JSON list ('[3, 4]'), got {args.args!r}",
                  file=sys.stderr)
            return 2
        spec = _spec(c, args.tag, args.task)
        if spec is not None and len(spec.get("args") or []) == 1 and len(task_args) != 1 and args.args:
            task_args = [task_args]  # followPath '[[3, 4], [5, 6]]': the one argument, not the list of them
        bad = _off_map(c, spec, task_args)
        if bad:
            print(f"error: {bad}; the task was not given", file=sys.stderr)
            return 1
        out = c.give(args.tag, args.task, task_args, queue=args.queue)
        if not args.json:
            extra = f" (interrupts task {out['interrupts']})" if out.get("interrupts") else ""
            print(f"task {out['task_id']} given to robot {args.tag}: {args.task} {task_args} "
                  f"[{out['mode']}]{extra}")
    elif args.cmd == "stop":
        out = c.stop(args.tag)
        if not args.json:
            print(f"robot {out['tag']} halted at ({out['x']:.2f}, {out['y']:.2f}) in {out['ms']:.1f} ms; "
                  f"cancelled tasks: {out['cancelled'] or 'none'}")
    elif args.cmd in ("upload", "unload", "sandbox-reset"):
        tags = args.tags
        if args.cmd == "sandbox-reset":
            out = c.sandbox_reset(tags)
            if not args.json:
                for row in out["results"]:
                    print(f"robot {row.get('tag')}: {row.get('message')}")
        elif args.cmd == "unload":
            out = c.unload(tags, args.name)
            if not args.json:
                print(f"{args.name} unloaded from robots {', '.join(map(str, out['tags']))}")
        else:
            path = Path(args.file)
            try:
                source = path.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError) as e:
                print(f"error: cannot read {path}: {e}", file=sys.stderr)
                return 2
            out = c.upload(tags, path.name, source, run=args.run)
            if not args.json:
                if out.get("pending"):
                    print(out.get("message"))
                for row in out.get("results", []):
                    print(f"robot {row.get('tag')}: {'ok' if row.get('ok') else 'REFUSED'} {row.get('message', '')}")
            if out.get("results") and not out.get("ok", True):
                if args.json:
                    print(json.dumps(out, default=_jsonable))
                return 1
    elif args.cmd == "extensions":
        out = c.extensions(args.tag)
        if not args.json:
            if not out:
                print(f"robot {args.tag} has no uploaded modules")
            for mod in out:
                print(f"{mod['name']} {mod['version']} ({mod['kind']}, {mod['file']}, sha256 {mod['sha256'][:12]}): "
                      f"{', '.join(mod['tasks'])}")
    elif args.cmd == "match":
        out = c.match(args.action, args.seconds, rule=args.rule)
        if not args.json:
            print(_clock(out))
    elif args.cmd == "teamwork":
        body: dict[str, Any] = {} if args.setting is None else {"reallocate": args.setting == "on"}
        if args.team:
            body["team"] = args.team
        out = c.request("teamwork", **body)
        if not args.json:
            state = "on" if out["reallocate"] else "off"
            moved = f"; moved now: tasks {', '.join(map(str, out['moved']))}" if out.get("moved") else ""
            print(f"team {out['team']}: reallocation of a lost robot's tasks is {state}{moved}")
    elif args.cmd == "score":
        out = c.score()
        if not args.json:
            _print_score(out)
    elif args.cmd == "recovery":
        out = c.request("stats").get("recovered") or {}
        if not args.json:
            if not out:
                print("the core started on an empty state folder: nothing was recovered")
            else:
                print(f"recovered {out['events']} events in {out['seconds']:.2f} s"
                      + (f"; {out['legacy_records']} of them of the previous log format (no checksums)"
                         if out.get("legacy_records") else ""))
                print(out.get("damage") or "the event log is undamaged")
                if out.get("clock"):
                    print(out["clock"])
    elif args.cmd == "events":
        return _events(c, args)
    else:  # pragma: no cover - argparse prevents it
        return 2
    if args.json:
        print(json.dumps(out, default=_jsonable))
    return 0


def _task_args(words: list[str]) -> list[Any] | None:
    """``['3', '4']`` → ``[3, 4]``; ``['[3, 4]']`` → ``[3, 4]``; a word that is no JSON value is
    taken as text (a name); ``None`` for a malformed JSON list."""
    if len(words) == 1 and words[0].lstrip().startswith("["):
        try:
            v = json.loads(words[0])
        except ValueError:
            return None
        return v if isinstance(v, list) else [v]
    out: list[Any] = []
    for w in words:
        try:
            out.append(json.loads(w))
        except ValueError:
            out.append(w)
    return out


def _spec(c: Client, tag: int, task: str) -> dict[str, Any] | None:
    """The task as the robot advertises it (None: unknown here; the give itself says why)."""
    try:
        return next((s for s in c.tasks(tag)["advertised"] if s.get("name") == task), None)
    except (RoboCompError, KeyError, TypeError):
        return None


def _off_map(c: Client, spec: dict[str, Any] | None, args: list[Any]) -> str | None:
    """Why a cell among the task's arguments cannot be a goal (a wall, outside the arena), going by
    the arguments the robot advertises for the task (``x``/``y`` and ``points``), else None."""
    if spec is None:
        return None
    names = [a.get("name") for a in spec.get("args") or []]
    cells: list[Any] = []
    if "x" in names and "y" in names and len(args) > max(names.index("x"), names.index("y")):
        cells.append((args[names.index("x")], args[names.index("y")]))
    for i, a in enumerate(spec.get("args") or []):
        if a.get("type") == "points" and i < len(args) and isinstance(args[i], list):
            cells += [tuple(p) for p in args[i] if isinstance(p, (list, tuple)) and len(p) == 2]
    if not cells:
        return None
    from robo_comp.protocol import unpack_walls

    walls = unpack_walls(c.arena())
    h, w = walls.shape
    for x, y in cells:
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (x, y)):
            continue  # the robot's own argument check names it
        cx, cy = int(round(x)), int(round(y))
        if not (0 <= cx < w and 0 <= cy < h):
            return f"({x}, {y}) is outside the {w}×{h} arena"
        if walls[cy, cx]:
            return f"({x}, {y}) is a wall; pick a free cell (robo-comp plan shows the map)"
    return None


def _clock(s: dict[str, Any]) -> str:
    rem = s.get("remaining")
    return (f"match {s.get('phase', '?')}; " + (f"{rem:.0f} s left" if rem is not None else "no time limit")
            + (f"; a core outage: the clock {'stands still' if s['outage'] == 'pause' else 'counts it'}"
               if s.get("outage") else ""))


def _print_score(s: dict[str, Any]) -> None:
    print(_clock(s))
    print(f"{'rank':>4} {'team':<10} {'score':>8} {'victims':>7} {'penalties':>9}")
    for row in s.get("teams", []):
        dq = "  disqualified" if row.get("disqualified") else ""
        print(f"{row.get('rank', 0):>4} {row['team']:<10} {row['score']:>8g} {row['victims']:>7} "
              f"{row['penalties']:>9g}{dq}")


def _jsonable(o: Any) -> Any:
    if isinstance(o, bytes):
        return f"<{len(o)} bytes>"
    raise TypeError(type(o).__name__)


def _events(c: Client, args: argparse.Namespace) -> int:
    n = 0
    t_end = time.monotonic() + args.timeout if args.timeout else None
    sub = None
    if args.public:
        sub = c.subscribe()
    else:
        c.watch(True)
    while (not args.count or n < args.count) and (t_end is None or time.monotonic() < t_end):
        left = 1.0 if t_end is None else max(0.0, min(1.0, t_end - time.monotonic()))
        if sub is not None:
            if not sub.poll(int(left * 1000)):
                continue
            topic, data = recv_event(sub)
            ev: dict[str, Any] = {"topic": topic, "data": data}
        else:
            got = c.next_event(left)
            if got is None:
                continue
            ev = got
        topic = str(ev["topic"])
        if args.topic and not any(topic.startswith(p) for p in args.topic):
            continue
        if any(topic.startswith(p) for p in args.skip):
            continue
        n += 1
        if args.json:
            print(json.dumps(ev, default=_jsonable), flush=True)
        else:
            print(f"{ev['topic']:<16} {json.dumps(ev['data'], default=_jsonable)}", flush=True)
    if sub is not None:
        sub.close(0)
    return 0
