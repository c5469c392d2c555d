"""``robo-comp ctl``: a scriptable console for teams and the referee (text or ``--json``)."""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from robo_comp.client import Client, read_token, recv_event, resolve_core
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
                        description="Example: give 101 goTo '[3, 4]'")
    g.add_argument("tag", type=int)
    g.add_argument("task", help="task name as the robot advertises it (see 'tasks TAG')")
    g.add_argument("args", nargs="?", default="[]", help="arguments as a JSON list, e.g. '[3, 4]'")
    g.add_argument("--queue", action="store_true", help="queue the task instead of interrupting")
    u = cmds.add_parser("upload", help="upload an extension or code module to robots",
                        description="Example: upload 101,102 square.py. The module is checked on each robot "
                                    "(docs/sandbox.md); a refusal names the file, line and rule.")
    u.add_argument("tags", help="robot tag, or several separated by commas")
    u.add_argument("file", help="the module (.py)")
    u.add_argument("--run", action="store_true", help="run the module's first task now (code that runs now)")
    x = cmds.add_parser("extensions", help="the modules uploaded to a robot")
    x.add_argument("tag", type=int)
    un = cmds.add_parser("unload", help="take an uploaded module away from robots")
    un.add_argument("tags", help="robot tag, or several separated by commas")
    un.add_argument("name", help="the module's MANIFEST name")
    sr = cmds.add_parser("sandbox-reset", help="referee: restart the team-code sandbox of robots now",
                         description="A sandbox whose code hit its limits too often rests (60 s, doubling) "
                                     "and restarts by itself; this restarts it at once.")
    sr.add_argument("tags", help="robot tag, or several separated by commas")
    m = cmds.add_parser("match", help="referee: start, pause, resume, finish or extend the match")
    m.add_argument("action", choices=("start", "pause", "resume", "finish", "extend"))
    m.add_argument("--seconds", type=float, help="for extend: seconds to add")
    cmds.add_parser("score", help="the scoreboard, phase and clock")
    e = cmds.add_parser("events", help="print events as they happen")
    e.add_argument("--count", type=int, default=0, help="stop after N events (0 = never)")
    e.add_argument("--timeout", type=float, default=0.0, help="stop after S seconds (0 = never)")
    e.add_argument("--public", action="store_true", help="read the public wall feed instead of your own events")
    p.set_defaults(func=run)


def add_connection_args(p: argparse.ArgumentParser, required: bool = True) -> None:
    """``--core``, ``--token``/``--token-file`` and the CurveZMQ ``--curve-cert``/``--core-key``,
    shared by every client command (``required=False`` where another source may replace the core,
    as the wall's ``--replay``)."""
    from robo_comp.protocol.curve import add_curve_args

    p.add_argument("--core", required=required,
                   help="ROUTER URL (tcp://HOST:PORT), the core's state folder, or mdns:NAME (a core started "
                        "with --advertise NAME on this LAN)")
    tok = p.add_mutually_exclusive_group(required=required)
    tok.add_argument("--token", help="team or referee token")
    tok.add_argument("--token-file", help="file holding the token")
    add_curve_args(p)


def _print_robots(rows: list[dict[str, Any]]) -> None:
    print(f"{'tag':>5} {'team':<8} {'status':<10} {'x':>7} {'y':>7} {'head':>5}  {'task':<22} queue")
    for r in rows:
        task = r["task"]
        label = f"{task['name']}#{task['task_id']}" if task else "-"
        print(f"{r['tag']:>5} {r['team']:<8} {r['status']:<10} {r['x']:>7.2f} {r['y']:>7.2f} "
              f"{r['heading']:>5.0f}  {label:<22} {r['queue']}")


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
            for k, v in out.items():
                print(f"{k:>14}: {v}")
    elif args.cmd == "tasks":
        out = c.tasks(args.tag)
        if not args.json:
            _print_tasks(out)
    elif args.cmd == "give":
        try:
            task_args = json.loads(args.args)
        except ValueError:
            print(f"error: arguments must be a JSON list such as '[3, 4]', got {args.args!r}", file=sys.stderr)
            return 2
        if not isinstance(task_args, list):
            task_args = [task_args]
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
        try:
            tags = [int(t) for t in args.tags.split(",") if t.strip()]
        except ValueError:
            print(f"error: tags must be numbers separated by commas, got {args.tags!r}", file=sys.stderr)
            return 2
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
        out = c.match(args.action, args.seconds)
        if not args.json:
            print(_clock(out))
    elif args.cmd == "score":
        out = c.score()
        if not args.json:
            _print_score(out)
    elif args.cmd == "events":
        return _events(c, args)
    else:  # pragma: no cover - argparse prevents it
        return 2
    if args.json:
        print(json.dumps(out, default=_jsonable))
    return 0


def _clock(s: dict[str, Any]) -> str:
    rem = s.get("remaining")
    return f"match {s.get('phase', '?')}; " + (f"{rem:.0f} s left" if rem is not None else "no time limit")


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
            if not sub.poll(left * 1000):
                continue
            topic, data = recv_event(sub)
            ev = {"topic": topic, "data": data}
        else:
            ev = c.next_event(left)
            if ev is None:
                continue
        n += 1
        if args.json:
            print(json.dumps(ev, default=_jsonable), flush=True)
        else:
            print(f"{ev['topic']:<16} {json.dumps(ev['data'], default=_jsonable)}", flush=True)
    if sub is not None:
        sub.close(0)
    return 0
