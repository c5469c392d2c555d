"""``robo-comp web``: watch a match (or a recorded one) in a browser.

    robo-comp web --core STATE_OR_URL [--token-file STATE/referee.token] [--port 8080]
    robo-comp web --replay STATE/events.log [--port 8080]

Then open the printed URL. Run it as ``robo-comp web`` (or ``python -m robo_comp.web.cli``).
"""
from __future__ import annotations

import argparse
import asyncio
import socket
import sys
from pathlib import Path
from typing import Any

from robo_comp.errors import FieldError, RoboCompError


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The gateway's options."""
    from robo_comp.client import add_connection_args

    add_connection_args(p, required=False)
    p.add_argument("--replay", metavar="LOG", help="serve a recorded match (a core's STATE/events.log) instead")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to serve on (default 127.0.0.1; 0.0.0.0 for every network)")
    p.add_argument("--port", type=int, default=8080, help="HTTP port (default 8080; 0 picks a free one)")
    p.add_argument("--view-token-file", metavar="FILE", action="append", default=[],
                   help="a team's token file: the gateway offers that team's private view through a link it "
                        "prints (the link holds a key made from the token, never the token; a page without "
                        "the link or the token gets only the public view); repeatable")
    p.add_argument("--allow-origin", metavar="ORIGIN", action="append", default=[],
                   help="a page origin besides the gateway's own that may open its WebSocket, e.g. "
                        "https://match.example.org when a proxy serves the page under that name "
                        "(repeatable; pages of every other site are refused)")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``web`` subcommand."""
    p = subparsers.add_parser("web", help="watch the match live or a replay in a browser",
                              description="A web gateway: the match (or a recorded one) on a page with "
                                          "map, robots, finds, scoreboard and replay controls. See docs/web.md.")
    add_arguments(p)
    p.set_defaults(func=run)


def _gateway(args: argparse.Namespace) -> Any:
    from robo_comp.client import read_token

    try:
        from robo_comp.web.server import LiveGateway, ReplayGateway
    except ImportError as e:
        raise FieldError(f"robo-comp web needs the 'web' extra ({e.name} is missing): "
                         "pip install -e '.[web]' (make test installs it)") from None

    if args.replay:
        if args.core:
            raise FieldError("give either --core (a live match) or --replay LOG, not both")
        return ReplayGateway(args.replay)
    if not args.core:
        raise FieldError("give --core URL_OR_STATE_FOLDER (a live match) or --replay STATE/events.log")
    token_file = args.token_file
    if not args.token and not token_file:
        ref = Path(args.core) / "referee.token"
        if "://" in args.core or not ref.is_file():
            raise FieldError("give --token-file: the gateway says hello to the core with a token (the referee's "
                             "shows idle robots from the start; browsers still get only the public feed)")
        token_file = str(ref)
    views: dict[str, str] = {}
    for f in args.view_token_file:
        views[Path(f).stem] = read_token(None, f)
    token = read_token(args.token, token_file)
    _check_token(args, token)
    return LiveGateway(args.core, token, private_tokens=views, curve_cert=args.curve_cert, core_key=args.core_key)


def _check_token(args: argparse.Namespace, token: str) -> None:
    """Say hello once before serving: a refused token is an error now, not on every page; a core
    that is not up yet is only a warning (the gateway keeps trying)."""
    from robo_comp.client import Client
    from robo_comp.errors import TimeoutError_

    try:
        Client(args.core, token, client="web", timeout=2.0, curve_cert=args.curve_cert,
               core_key=args.core_key).close()
    except TimeoutError_ as e:
        print(f"robo-comp web: warning: {e.message} The gateway keeps trying; pages say so meanwhile.",
              file=sys.stderr)
    except FieldError as e:
        if "neither a URL" not in e.message:  # no core.json yet: the core may start later
            raise
        print(f"robo-comp web: warning: {e.message}; the gateway keeps looking for it", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    """Serve until interrupted."""
    if not 0 <= args.port <= 65535:
        raise FieldError(f"--port must be 0..65535, not {args.port}")
    gw = _gateway(args)
    import uvicorn

    from robo_comp.web.server import OriginCheck, make_app, view_key
    from robo_comp.web.wire import config

    for o in args.allow_origin:
        OriginCheck.normalise(o)  # a malformed origin is an error now, not a silent refusal later

    try:
        sock = socket.socket(socket.AF_INET6 if ":" in args.host else socket.AF_INET, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((args.host, args.port))
        sock.listen(2048)  # browsers that come before the server is up wait in the backlog
    except OSError as e:
        raise FieldError(f"cannot serve on {args.host}:{args.port} ({e.strerror}); is another server using "
                         "that port? (--port 0 picks a free one)") from None
    port = sock.getsockname()[1]
    host = "127.0.0.1" if args.host in ("0.0.0.0", "::") else args.host
    server = uvicorn.Server(config(make_app(gw, allow_origins=args.allow_origin)))
    what = f"replay of {args.replay}" if args.replay else f"live match at {args.core}"
    print(f"web: serving the {what} on http://{host}:{port}/", flush=True)
    for name, tok in sorted(getattr(gw, "private_tokens", {}).items()):
        print(f"web: {name}'s private view (give this link to {name} only): "
              f"http://{host}:{port}/#view={name}&key={view_key(tok)}", flush=True)
    asyncio.run(server.serve(sockets=[sock]))
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m robo_comp.web.cli``: the gateway without the ``robo-comp`` front command."""
    p = argparse.ArgumentParser(prog="robo-comp web", description="Watch a match in a browser.")
    add_arguments(p)
    args = p.parse_args(argv)
    try:
        return run(args)
    except RoboCompError as e:
        print(f"robo-comp web: {e.message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
