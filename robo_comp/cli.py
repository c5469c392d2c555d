"""``robo-comp``: the one command with subcommands for every part of the system."""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import Any

from robo_comp import __version__
from robo_comp.errors import FieldError, RoboCompError


def _positive(text: str) -> float:
    """An argparse type: a number above zero."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r} must be a number above zero")
    return value


def _positive_int(text: str) -> int:
    """An argparse type: a whole number above zero."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be above zero")
    return value


def _running_core(state: Path) -> int | None:
    """The pid of a live core serving ``state`` (from its core.json), else None."""
    import json
    import os

    try:
        pid = int(json.loads((state / "core.json").read_text())["pid"])
        cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if pid == os.getpid() or "robo" not in cmd or " core" not in cmd:
        return None  # core.json of a core that is gone (its pid now another program's, or none)
    return pid


def _core(args: argparse.Namespace) -> int:
    import shutil

    import zmq

    state = Path(args.state)
    pid = _running_core(state)
    if pid is not None:
        raise FieldError(f"a core (pid {pid}) is already serving {state}; stop it first, or give another --state "
                         "folder for a second match")
    if args.scenario and not Path(args.scenario).is_file():  # a bundled scenario's name, as the league takes
        from robo_comp.world.scenario import resolve_scenario

        args.scenario = str(resolve_scenario(args.scenario))
    made = not state.exists()
    try:
        return _serve(args, state)
    except (zmq.ZMQError, OSError) as e:
        if made:  # leave no half-made folder behind
            shutil.rmtree(state, ignore_errors=True)
        if isinstance(e, zmq.ZMQError) and e.errno == zmq.EADDRINUSE:
            raise FieldError(f"cannot listen: {e}; another core or program has that port: give --port N, or "
                             "--port 0 for any free port") from None
        raise FieldError(f"cannot start the core with state in {state}: {e}") from None


def _serve(args: argparse.Namespace, state: Path) -> int:
    """Start (recover) the match's core, waiting for room on a full disk, and serve until stopped."""
    from robo_comp.core import room
    from robo_comp.errors import StorageError

    while True:
        try:
            core, recovering = _start_core(args, state)
            break
        except OSError as e:
            if not room.no_room(e):
                raise
            said = room.full_disk(state, e)
            if args.on_full_disk == "exit":
                raise StorageError(f"{said}, then start the core again.") from None
            print(f"core: {said}; the core starts by itself once there is room (it checks every second; "
                  "Ctrl-C gives up).", file=sys.stderr, flush=True)
            waited = room.wait_for_room(state)
            print(f"core: there is room again after {waited:.0f} s; starting", file=sys.stderr, flush=True)
    if recovering:
        print(f"core: recovered the match of {state} (settings from {state / 'match.json'})", flush=True)
    print(f"core: serving {core.scenario.name!r} for teams {', '.join(core.tokens.teams)} on "
          f"tcp://{args.host}:{core.port} (events on port {core.pub_port}); state in {args.state}"
          f"{'; CurveZMQ on (keys in ' + str(Path(args.state) / 'keys') + ')' if core.curve else ''}",
          flush=True)
    advert = None
    if args.advertise:  # off unless the organiser asks: the core is found on the LAN by this name
        from robo_comp.discovery import advertise
        from robo_comp.protocol import PROTOCOL_VERSION

        advert = advertise(args.advertise, args.host, core.port, core.pub_port, curve=core.curve,
                           protocol=PROTOCOL_VERSION)
        print(f"core: advertised on the LAN as mdns:{args.advertise} (clients: --core mdns:{args.advertise})",
              flush=True)
    try:
        core.run()
    finally:
        if advert is not None:
            advert.close()
    return 0


def _start_core(args: argparse.Namespace, state: Path) -> tuple[Any, bool]:
    """Recover or create the match, bind and record it: ``(core, recovering)``. An ``OSError``
    (a full disk) leaves nothing open behind it, so that the start can be tried again."""
    from robo_comp.core import matchfile
    from robo_comp.core.server import Core
    from robo_comp.world.scenario import default_scenario, load_scenario

    given = {"teams": [t.strip() for t in args.teams.split(",") if t.strip()] if args.teams else None,
             "scenario": str(Path(args.scenario).resolve()) if args.scenario else None,
             "scenario_sha256": matchfile.scenario_hash(args.scenario),
             "practice": args.practice, "approve_uploads": args.approve_uploads, "rules": args.rules,
             "curve": args.curve, "pose_hz": args.pose_hz, "heartbeat": args.heartbeat, "port": args.port,
             "robots": args.robots, "max_speed": args.max_speed, "debug_replay": args.debug_replay}
    settings, recovering = matchfile.resolve(state, given, args.override)
    scenario_file = settings.get("scenario")
    if recovering and scenario_file and not args.scenario:
        if matchfile.scenario_hash(scenario_file) != settings.get("scenario_sha256"):
            raise FieldError(f"the scenario file {scenario_file} changed since this match started; put the "
                             "match's version back, or give --scenario FILE --override to play on with this one")
    scenario = load_scenario(scenario_file) if scenario_file else default_scenario()
    pm = None
    if settings.get("rules"):
        from robo_comp.plugins.manager import load_rules

        pm = load_rules(settings["rules"])
    practice = bool(settings.get("practice")) or not scenario_file
    core = Core(state, scenario, settings.get("teams"), host=args.host, port=settings.get("port", 5555),
                heartbeat=settings.get("heartbeat", 1.0), fsync=args.fsync, plugins=pm,
                practice=practice, approve_uploads=bool(settings.get("approve_uploads")),
                curve=bool(settings.get("curve")), pose_hz=settings.get("pose_hz", 10.0),
                robots_per_team=settings.get("robots"), max_speed=settings.get("max_speed"),
                max_connections=args.max_connections, max_per_address=args.max_per_address)
    core.debug_replay = settings.get("debug_replay") or "team"  # recorded in the log's core.started
    try:
        core.bind(lambda: matchfile.write(state, {
            "teams": core.tokens.teams, "scenario": scenario_file,
            "scenario_sha256": settings.get("scenario_sha256"), "practice": practice,
            "approve_uploads": bool(settings.get("approve_uploads")),
            "rules": settings.get("rules"), "curve": bool(settings.get("curve")),
            "pose_hz": settings.get("pose_hz", 10.0), "heartbeat": core.heartbeat,
            "port": core.port, "robots": core.match.robots_per_team,
            "max_speed": settings.get("max_speed"), "debug_replay": core.debug_replay}))
    except OSError:
        core.close()
        raise
    return core, recovering


def _robots(args: argparse.Namespace) -> int:
    from robo_comp.client import read_token, resolve_core
    from robo_comp.protocol.curve import client_keys
    from robo_comp.robots.host import RobotHost

    truth = None
    if args.scenario:  # an organiser-run host knows the truth, so its camera shows victims
        from robo_comp.world.scenario import load_scenario

        from robo_comp.world.scenario import resolve_scenario

        truth = load_scenario(resolve_scenario(args.scenario))  # a file or a bundled scenario's name
    from robo_comp.sandbox import oswall

    oswall.at_start("robots", args.os_sandbox)  # a host that cannot wall team code stops here, saying so
    token = read_token(args.token, args.token_file)
    options: dict[str, object] = {}
    if args.driver == "er1":
        rcc = [a.strip() for a in (args.rcc or "").split(",") if a.strip()]
        if len(rcc) != args.count:
            raise FieldError(f"--driver er1 needs one --rcc HOST:PORT per robot ({args.count}), "
                             f"got {len(rcc)}")
        options["rcc"] = rcc
    elif args.driver == "ros2":
        options.update(_ros2_options(args))
    host = RobotHost(resolve_core(args.core), token, args.count,
                     prefix=args.prefix, speed=args.speed, report_hz=args.report_hz, sensor_hz=args.sensor_hz,
                     seed=args.seed,
                     truth=truth, driver=args.driver, driver_options=options,
                     curve=client_keys(args.core, token, args.curve_cert, args.core_key),
                     positioning=_positioning(args.positioning), truth_pub=args.truth_pub,
                     camera_key=args.camera_key or _default_camera_key(args.core, args.positioning),
                     planner=args.planner)
    host.run(duration=args.duration or None)
    return 0


def _default_camera_key(core: str, positioning: str | None) -> str | None:
    """The camera's public certificate when the host runs beside the core (``--core STATE``) and
    ``robo-comp keys`` made it there: ``STATE/keys/organiser.key``."""
    if positioning is None:
        return None
    key = Path(core) / "keys" / "organiser.key"
    return str(key) if key.is_file() else None


def _ros2_options(args: argparse.Namespace) -> dict[str, object]:
    """The ``ros2`` driver's options from ``--ros2-ns``, ``--ros2-domain`` and ``--ros2-speed``."""
    import os

    names = [a.strip().strip("/") for a in (args.ros2_ns or "").split(",")]
    if len(names) != args.count or (args.count > 1 and not all(names)):
        raise FieldError(f"--driver ros2 needs one --ros2-ns NAMESPACE per robot ({args.count}), "
                         f"got {args.ros2_ns!r}")
    domain = args.ros2_domain if args.ros2_domain is not None else os.environ.get("ROS_DOMAIN_ID", "0")
    try:
        dom = int(domain)
    except ValueError:
        raise FieldError(f"the ROS 2 domain id must be a whole number, not {domain!r}") from None
    if not 0 <= dom <= 232:
        raise FieldError(f"the ROS 2 domain id must be 0..232, not {dom}")
    return {"ros2_ns": names, "ros2_domain": dom, "ros2_speed": args.ros2_speed}


def _positioning(spec: str | None) -> str | None:
    if spec is None:
        return None
    kind, _, url = spec.partition(":")
    if kind != "camera" or not url:
        raise FieldError(f"--positioning takes camera:URL (a robo-comp camera run --pub address), not {spec!r}")
    return url


def _replay(args: argparse.Namespace) -> int:
    import tempfile

    from robo_comp.core.replay import ReplayCore

    state = Path(args.state) if args.state else Path(tempfile.mkdtemp(prefix="robo_comp_replay_"))
    core = ReplayCore(Path(args.log), state, speed=args.speed, start_at=args.start, host=args.host,
                      port=args.port, exit_at_end=args.exit_at_end, curve=args.curve)
    core.bind()
    print(f"replay: {args.log} ({core.duration:.0f} s recorded) at {args.speed:g}x on tcp://{args.host}:{core.port}; "
          f"state in {state} (tokens: {state}/referee.token, {state}/teams/)", flush=True)
    core.run()
    return 0


def _demo(args: argparse.Namespace) -> int:
    from robo_comp.demo import run_demo

    duration = args.duration if args.duration is not None else (120.0 if args.web is not None else 20.0)
    return run_demo(duration=duration, robots=args.robots, web=args.web, camera=args.camera)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``robo-comp`` with every subcommand."""
    from robo_comp import ctl
    from robo_comp.league import cli as league_cli
    from robo_comp.world import generate_cli, plan_cli

    parser = argparse.ArgumentParser(
        prog="robo-comp", description="Multi-robot search-and-rescue competitions: core, robots, consoles.")
    parser.add_argument("--version", action="version", version=f"robo-comp {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log more")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    c = sub.add_parser("core", help="run the core (ROUTER + PUB) for a match",
                       description="Run the core. Writes STATE/core.json, team tokens in "
                                   "STATE/teams/<team>.token and STATE/referee.token (mode 0600), and "
                                   "the match's settings in STATE/match.json. On a state folder that holds "
                                   "a match, the core recovers it with its recorded teams, scenario, rules, "
                                   "port and options; an option that contradicts them is refused "
                                   "(--override applies it).")
    c.add_argument("--state", required=True, help="state folder (tokens, core.json, event log)")
    c.add_argument("--scenario", help="scenario file (TOML) or a bundled scenario's name (demo_room, office, "
                                      "big_rooms); default: the built-in arena")
    c.add_argument("--teams", help="comma-separated team names (default: the scenario's teams)")
    c.add_argument("--host", default="127.0.0.1", help="address to bind (0.0.0.0 for a LAN)")
    c.add_argument("--port", type=int, help="ROUTER port (0 = any free port; default 5555, or the recovered match's)")
    c.add_argument("--heartbeat", type=float, help="heartbeat interval in seconds (default 1)")
    c.add_argument("--fsync", action="store_true", help="fsync the event log every loop turn")
    c.add_argument("--pose-hz", type=_positive,
                   help="robot.positions batches per team per second; reports in between are "
                        "conflated, the newest pose wins (default 10)")
    c.add_argument("--practice", action="store_true", default=None,
                   help="no match phases: running at once, no time limit (the default without --scenario)")
    c.add_argument("--approve-uploads", action="store_true", default=None,
                   help="a team's upload during a running match waits for the referee's approval")
    c.add_argument("--rules", metavar="MODULE:OBJECT",
                   help="scoring rules plugin to use instead of the default search-and-rescue rules")
    c.add_argument("--curve", action="store_true", default=None,
                   help="CurveZMQ for a networked match: encrypted sockets, only the keys in STATE/keys "
                        "get in (run 'robo-comp keys --state STATE' first)")
    c.add_argument("--robots", type=int, metavar="N",
                   help="robots each team may register at most (default: what the scenario gives each team)")
    c.add_argument("--max-speed", type=_positive, metavar="CELLS_PER_S",
                   help="the fastest a robot may drive: a robot host's declared speed is cut to it, and a "
                        "reported pose farther than that from the last one is refused (default: 4x the "
                        "scenario's robot speed)")
    c.add_argument("--advertise", metavar="NAME",
                   help="let robots and consoles on the LAN find this core by name (--core mdns:NAME), over "
                        "mDNS on the interface of --host (off by default; docs/organiser.md)")
    c.add_argument("--debug-replay", choices=("team", "everyone"),
                   help="who sees a team's debug drawing (robot.draw_dot/line/text) in replays: only that team "
                        "and the referee (default), or everyone after the match; live it is always the team's "
                        "own (recorded in the log)")
    c.add_argument("--override", action="store_true",
                   help="on a restart, apply options that contradict the recovered match (and record them)")
    c.add_argument("--max-connections", type=_positive_int, metavar="N",
                   help="connections the core holds at most (default: what its open-file limit allows, "
                        "raised to the hard limit; the last 64 are kept for the referee and hosts)")
    c.add_argument("--max-per-address", type=_positive_int, metavar="N",
                   help="connections from one peer address at most; more are cut at once (default 256)")
    c.add_argument("--on-full-disk", choices=("wait", "exit"), default="wait",
                   help="when the state folder's disk is too full to start: say so and wait until there is "
                        "room, then start (default), or say so and exit")
    c.set_defaults(func=_core)

    r = sub.add_parser("robots", help="host simulated robots of one team",
                       description="Host N simulated robots; they register, take tasks, report "
                                   "positions and reconnect on their own.")
    from robo_comp.client import add_connection_args

    add_connection_args(r)
    r.add_argument("--count", type=int, default=3, help="number of robots")
    r.add_argument("--prefix", help="robot id prefix (ids PREFIX-1..N; default: the team name)")
    r.add_argument("--speed", type=float, help="cells per second (default: the scenario's robot speed)")
    r.add_argument("--report-hz", type=float, default=10.0, help="position reports per second")
    r.add_argument("--sensor-hz", type=_positive, default=2.0, metavar="HZ",
                   help="range sensor readings per second (default 2: a sensing period of 0.5 s); a moving "
                        "robot's readings go out once a sensing period, a standing robot's when they change, "
                        "at most once a sensing period")
    r.add_argument("--seed", type=int, default=0)
    from robo_comp.robots.planning import PLANNER_CHOICES, PROCESS_FROM

    r.add_argument("--planner", choices=PLANNER_CHOICES, default="auto",
                   help="where paths are planned: process: a process of its own at the lowest priority (a "
                        "busy host's stops never wait behind a plan); thread: a thread of the host; auto "
                        f"(default): a process from {PROCESS_FROM} robots, else a thread")
    r.add_argument("--scenario", help="the match's scenario file (organisers only): the camera then shows victims")
    r.add_argument("--duration", type=float, default=0.0, help="exit after S seconds (0 = run until stopped)")
    r.add_argument("--driver", choices=("sim", "er1", "ros2"), default="sim",
                   help="sim: simulated robots (default); er1: real ER1 robots through their robot control "
                        "centers; ros2: ROS 2 robots over DDS (pip install 'robo_comp[ros2]'; docs/robots.md)")
    r.add_argument("--rcc", metavar="HOST:PORT[,HOST:PORT...]",
                   help="for --driver er1: each robot's robot control center (one per robot, in order)")
    r.add_argument("--camera-key", metavar="CERT",
                   help="the overhead camera's public certificate (STATE/keys/organiser.key): fixes are "
                        "taken only over CurveZMQ from the camera holding its secret half (default: that "
                        "file in the --core state folder, when there is one)")
    r.add_argument("--ros2-ns", metavar="NS[,NS...]",
                   help="for --driver ros2: each robot's ROS 2 namespace (one per robot, in order; topics "
                        "/NS/cmd_vel, /NS/odom, /NS/scan)")
    r.add_argument("--ros2-domain", type=int, metavar="ID",
                   help="for --driver ros2: the robots' ROS_DOMAIN_ID (default: $ROS_DOMAIN_ID, else 0)")
    r.add_argument("--ros2-speed", type=_positive, default=0.2, metavar="M/S",
                   help="for --driver ros2: top speed in metres per second (default 0.2)")
    r.add_argument("--positioning", metavar="camera:URL",
                   help="take positions from an overhead camera (robo-comp camera run --pub URL) instead of "
                        "the simulated positioning system (docs/positioning.md)")
    r.add_argument("--truth-pub", metavar="URL",
                   help="simulation only: publish the robots' true poses here for synthetic cameras "
                        "(robo-comp camera run --synthetic URL)")
    from robo_comp.sandbox import oswall

    oswall.add_option(r)
    r.set_defaults(func=_robots)

    ctl.add_parser(sub)

    rp = sub.add_parser("replay", help="serve a recorded match (an event log) as if live, at any speed",
                        description="Play STATE/events.log of a match: walls and consoles connect to the "
                                    "replay as to a live core (read-only; commands are refused).")
    rp.add_argument("log", help="the event log (a core's STATE/events.log)")
    rp.add_argument("--speed", type=_positive, default=1.0, help="times real time (default 1)")
    rp.add_argument("--start", type=float, default=0.0, help="start this many seconds into the recording")
    rp.add_argument("--state", help="state folder of the replay (core.json, tokens; default: a new temporary one)")
    rp.add_argument("--host", default="127.0.0.1", help="address to bind")
    rp.add_argument("--port", type=int, default=0, help="ROUTER port (0 = any free port)")
    rp.add_argument("--exit-at-end", action="store_true", help="stop when the recording has been played")
    rp.add_argument("--curve", action="store_true",
                    help="CurveZMQ, as core --curve: the keys of the replay's --state folder, else the "
                         "recorded match's (STATE/keys beside the log)")
    rp.set_defaults(func=_replay)

    d = sub.add_parser("demo", help="run a demo match on localhost (what 'make demo' runs)")
    d.add_argument("--duration", type=float, help="seconds of match (default 20; 120 with --web)")
    d.add_argument("--robots", type=int, default=3, help="robots per team")
    d.add_argument("--web", type=int, metavar="PORT",
                   help="also show the match in a browser: serve the page on this port (see docs/web.md)")
    d.add_argument("--camera", action="store_true",
                   help="robots localize only from synthetic overhead-camera frames (docs/positioning.md)")
    d.set_defaults(func=_demo)

    plan_cli.add_parser(sub)
    generate_cli.add_parser(sub)
    league_cli.add_parser(sub)
    from robo_comp.world.overhead import cli as camera_cli

    camera_cli.add_parser(sub)
    from robo_comp import keys_cli

    keys_cli.add_parser(sub)
    from robo_comp.teams import newteam

    newteam.add_parser(sub)
    from robo_comp.tui import cli as tui_cli
    from robo_comp.wall import cli as wall_cli

    tui_cli.add_parsers(sub)
    wall_cli.add_parser(sub)
    from robo_comp.web import cli as web_cli

    web_cli.add_parser(sub)
    from robo_comp.export import cli as export_cli

    export_cli.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``robo-comp`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(asctime)s %(name)s %(levelname)s %(message)s")
    try:
        return int(args.func(args) or 0)
    except BrokenPipeError:  # `robo-comp ctl robots | head`: the reader has what it wanted
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
        return 0
    except RoboCompError as e:
        print(f"robo-comp {args.command}: {e.message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
