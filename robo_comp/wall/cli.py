"""``robo-comp wall``: show the arena live (or a recorded match) on a screen or a tiled display wall.

    robo-comp wall --core STATE_OR_URL --token-file STATE/referee.token
    robo-comp wall --core ... --token-file ... --grid 2x2 --tile 1,0 --size 1024x768   # one tile
    robo-comp wall --replay STATE/events.log --speed 4
    robo-comp wall --core ... --token-file ... --screenshot wall.png                   # headless

Run it as ``robo-comp wall`` (or ``python -m robo_comp.wall.cli``).
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Any

from robo_comp.errors import FieldError, RoboCompError
from robo_comp.wall.view import TileSpec, ViewState, parse_pair


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The wall's options (shared by ``robo-comp wall`` and ``python -m robo_comp.wall.cli``)."""
    from robo_comp.client import add_connection_args

    add_connection_args(p, required=False)  # --replay plays without a core
    p.add_argument("--size", default="1280x800", help="window (or tile) size WxH in pixels (default 1280x800)")
    p.add_argument("--grid", default="1x1", help="the wall is CxR tiles of --size each (default 1x1)")
    p.add_argument("--tile", default="0,0", help="which tile this process renders: c,r from 0,0 (default 0,0)")
    p.add_argument("--zoom", type=float, default=1.0, help="zoom on top of fit-to-canvas (default 1)")
    p.add_argument("--pan", default="0,0", help="map centre offset X,Y in cells (default 0,0)")
    p.add_argument("--view-pub", metavar="URL",
                   help="master tile: publish zoom/pan/open panels on this ZeroMQ URL (e.g. tcp://*:5601)")
    p.add_argument("--view-sub", metavar="URL",
                   help="follower tile: follow the master's view from this URL (e.g. tcp://wallhost:5601)")
    p.add_argument("--fps", type=float, default=30.0, help="frame rate cap (default 30)")
    p.add_argument("--no-trails", action="store_true", help="do not draw robot trails")
    p.add_argument("--fullscreen", action="store_true", help="full-screen window (one per projector/tile)")
    p.add_argument("--position", metavar="X,Y", help="window position on the desktop (several tiles on one host)")
    p.add_argument("--monitor", type=int, action="append", metavar="TAG", help="open a robot's monitor box at start")
    p.add_argument("--double-click", type=float, default=0.4, help="double-click interval in seconds")
    p.add_argument("--path-wait", type=float, default=1.0,
                   help="seconds after one point before it is sent as goTo (a second point starts a path)")
    p.add_argument("--replay", metavar="LOG", help="play a recorded match (a core's STATE/events.log)")
    p.add_argument("--speed", type=float, default=1.0, help="replay speed (default 1 = real time)")
    p.add_argument("--at", type=float, help="with --replay --screenshot: seconds into the match (default: its end)")
    p.add_argument("--screenshot", metavar="PNG", help="render one frame headless into PNG and exit")
    p.add_argument("--settle", type=float, default=0.5,
                   help="with --screenshot on a live core: seconds of events to take in first (default 0.5)")
    p.add_argument("--frames", type=int, default=0, help="exit after N frames (0 = run until closed)")


#: The wall's keys, for ``--help`` (docs/wall.md has the whole table).
KEYS = """keys: l legend on/off; d / D debug drawing (all, or the selected robot's / its team's);
+ - 0 and arrows zoom and pan; Esc drops the selection; q quits.
In a replay: [ and ] seek 10 s back and on, Home and End go to the start and the end, space
pauses and plays."""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``wall`` subcommand."""
    p = subparsers.add_parser("wall", help="show the arena live or a replay, on a screen or a tiled display wall",
                              description="The display wall: map, robots, finds, scoreboard, what happened (the "
                                          "ticker), the legend and the winner banner at the finish; click to "
                                          "inspect and command. See docs/wall.md.",
                              epilog=KEYS, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(p)
    p.set_defaults(func=run)


def _tile(args: argparse.Namespace) -> TileSpec:
    w, h = parse_pair(args.size, "x", "--size")
    cols, rows = parse_pair(args.grid, "x", "--grid")
    c, r = parse_pair(args.tile, ",", "--tile")
    return TileSpec(cols, rows, c, r, w, h)


def run(args: argparse.Namespace) -> int:
    """Run the wall (or take one screenshot) as the options say."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    if args.screenshot:
        os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    if args.position:
        x, y = parse_pair(args.position, ",", "--position")
        os.environ["SDL_VIDEO_WINDOW_POS"] = f"{x},{y}"
    import pygame

    from robo_comp.client import read_token
    from robo_comp.wall.app import LiveSource, WallApp
    from robo_comp.view.model import MatchView
    from robo_comp.wall.replay import ReplaySource

    tile = _tile(args)
    pan = parse_pair(args.pan, ",", "--pan", float)
    view = ViewState(args.zoom, pan[0], pan[1], monitors=list(args.monitor or []))
    model = MatchView()
    source: Any
    if args.replay:
        source = ReplaySource(args.replay, args.speed)
        source.attach(model)
    else:
        if not args.core:
            raise FieldError("give --core URL_OR_STATE_FOLDER (or --replay LOG)")
        source = LiveSource(args.core, read_token(args.token, args.token_file), curve_cert=args.curve_cert,
                            core_key=args.core_key)
        source.start(model)
    app = WallApp(model, tile, view, source=source, fps=args.fps, trails=not args.no_trails,
                  double_click=args.double_click, path_wait=args.path_wait,
                  view_pub=args.view_pub, view_sub=args.view_sub)
    try:
        if args.screenshot:
            pygame.display.init()
            pygame.font.init()
            if isinstance(source, ReplaySource):
                source.seek(model, source.duration if args.at is None else args.at)
            else:
                t_end = time.monotonic() + max(0.0, args.settle)
                while time.monotonic() < t_end:
                    source.sub.poll(50)
                    source.drain(model)
            app.refresh(time.monotonic() + 3600)
            path = app.screenshot(args.screenshot)
            print(f"wall: screenshot {path} ({tile.width}x{tile.height}, tile {tile.col},{tile.row} "
                  f"of {tile.cols}x{tile.rows})")
            return 0
        try:
            app.open_window(fullscreen=args.fullscreen)
        except pygame.error as e:
            raise FieldError(f"cannot open a window ({e}); on a machine without a screen use --screenshot PNG") from None
        app.run(max_frames=args.frames)
        return 0
    finally:
        app.close()


def main(argv: list[str] | None = None) -> int:
    """``python -m robo_comp.wall.cli``: the wall without the ``robo-comp`` front command."""
    p = argparse.ArgumentParser(prog="robo-comp wall", description="The robo_comp display wall.", epilog=KEYS,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(p)
    args = p.parse_args(argv)
    try:
        return run(args)
    except RoboCompError as e:
        print(f"robo-comp wall: {e.message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
