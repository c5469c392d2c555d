"""The pytest plugin of robo_comp: test team code against a real match or a seeded bench.

Installed with robo_comp (entry point ``pytest11``), so a team package's tests get these
fixtures without a ``conftest.py``:

``robo_scenario``
    Path of the scenario file the tests use: ``--robo-scenario`` on the command line, else the
    ``robo_comp_scenario`` ini option (a path relative to the rootdir, or the name of a bundled
    scenario such as ``demo_room``), else the bundled ``demo_room``.
``robo_team``
    The team the tests play for: ``--robo-team``, else the ``robo_comp_team`` ini option, else
    the scenario's first team.
``robo_match``
    A :class:`Match`: a **real core process** serving the scenario (practice mode: the match is
    running at once) in a temporary state folder. Start robot hosts with
    :meth:`Match.robots`, talk to it with :meth:`Match.client`; everything is stopped at
    teardown.
``robo_bench``
    A :class:`Bench`: the team's modules in the **real sandbox** (:class:`~robo_comp.plugins.sandbox.Sandbox`,
    a separate restricted process), its robot API answered by an in-process, seeded simulation
    of the scenario. Deterministic: the same code, scenario and seed give the same result.

Helpers: :func:`wait_for`, :func:`wait_robots`, :func:`next_event_where`.

In a real match, upload a module with ``client.upload(tags, filename, source)`` and give its
tasks like any other; on the bench the same module runs without a core.
"""
from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from subprocess import Popen
from typing import TYPE_CHECKING, Any

import pytest

from robo_comp.client import Client
from robo_comp.errors import BadTaskError, FieldError, UnavailableError
from robo_comp.launch import start_core, start_robots, stop_all

if TYPE_CHECKING:  # heavy imports (numpy, numba, the sandbox) only when a fixture needs them
    from robo_comp.plugins.contract import ModuleInfo
    from robo_comp.plugins.sandbox import Limits, LogLine, Sandbox
    from robo_comp.world.scenario import Scenario

DEFAULT_SCENARIO = "demo_room"
HEARTBEAT = 0.2
#: What the robot host allows (robo_comp/robots/teamcode.py): map_piece radius, evidence ids.
MAX_PIECE_RADIUS = 20
MAX_EVIDENCE = 32


# ---------------------------------------------------------------------- waiting helpers
def wait_for(pred: Callable[[], Any], timeout: float = 10.0, what: str = "condition") -> Any:
    """Poll ``pred`` every 50 ms until it returns a truthy value, and return that value.

    Raises AssertionError naming ``what`` after ``timeout`` seconds.
    """
    t_end = time.monotonic() + timeout
    while True:
        v = pred()
        if v:
            return v
        if time.monotonic() > t_end:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.05)


def wait_robots(client: Client, n: int, status: str = "connected", timeout: float = 30.0) -> list[dict[str, Any]]:
    """Wait until ``client`` sees at least ``n`` robots with ``status``; return those rows by tag."""
    def ready() -> list[dict[str, Any]] | None:
        rows = sorted((r for r in client.robots() if r["status"] == status), key=lambda r: r["tag"])
        return rows if len(rows) >= n else None
    return wait_for(ready, timeout, f"{n} {status} robots")


def next_event_where(client: Client, pred: Callable[[dict[str, Any]], bool],
                     timeout: float = 10.0) -> dict[str, Any]:
    """Read pushed events (after ``client.watch()``) until one satisfies ``pred``; return it.

    Events read before the match are consumed. Raises AssertionError after ``timeout`` s.
    """
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        ev = client.next_event(min(0.2, max(0.0, t_end - time.monotonic())))
        if ev is not None and pred(ev):
            return ev
    raise AssertionError(f"timed out after {timeout} s waiting for a matching event")


def resolve_scenario(spec: str | os.PathLike[str], base: Path | None = None) -> Path:
    """A scenario path from a path (relative to ``base``) or a bundled scenario's name."""
    from robo_comp.world.scenario import bundled_scenario_path

    p = Path(spec)
    if not p.is_absolute() and base is not None:
        p = base / p
    if p.is_file():
        return p.resolve()
    if str(spec).endswith(".toml") and (os.sep in str(spec) or "/" in str(spec)):
        raise FieldError(f"scenario file {spec!r} not found (looked in {p})")
    return bundled_scenario_path(str(spec))


# ---------------------------------------------------------------------- a real match
@dataclass
class Match:
    """A real core process (and the robot hosts started for it) in ``state``.

    Built by :func:`start_match` or the ``robo_match`` fixture; :meth:`close` stops it all.
    """

    state: Path
    scenario: Path | None
    proc: Popen[bytes]
    procs: list[Popen[bytes]] = field(default_factory=list)
    clients: list[Client] = field(default_factory=list)

    def token(self, team: str) -> str:
        """A team's token (``"referee"`` for the referee's), as the core wrote it."""
        path = self.state / ("referee.token" if team == "referee" else f"teams/{team}.token")
        return path.read_text().strip()

    def token_file(self, team: str) -> Path:
        """The token file of ``team`` (what ``--token-file`` takes)."""
        return self.state / ("referee.token" if team == "referee" else f"teams/{team}.token")

    @property
    def teams(self) -> list[str]:
        """The match's team names (from the token files)."""
        return sorted(p.stem for p in (self.state / "teams").glob("*.token"))

    def client(self, team: str, **kw: Any) -> Client:
        """A connected :class:`Client` for ``team`` or ``"referee"`` (closed at teardown)."""
        c = Client(str(self.state), self.token(team), **kw)
        self.clients.append(c)
        return c

    def referee(self) -> Client:
        """A client holding the referee's token."""
        return self.client("referee")

    def robots(self, team: str, count: int = 1, *extra: str, organiser: bool = True,
               speed: float | None = None) -> Popen[bytes]:
        """Start a ``robo-comp robots`` process with ``count`` robots of ``team``.

        ``organiser=True`` passes the scenario file (``--scenario``): the simulated camera then
        shows the hidden victims, as on the organiser's hosts in a match. ``speed`` is in
        cells per second (default: the scenario's). The output goes to ``robots-<team>.log``
        in the state folder.
        """
        args = list(extra)
        if organiser and self.scenario is not None:
            args += ["--scenario", str(self.scenario)]
        if speed is not None:
            args += ["--speed", str(speed)]
        p = start_robots(self.state, team, count, *args)
        self.procs.append(p)
        return p

    def start(self) -> dict[str, Any]:
        """Start the match as the referee (not needed in practice mode, where it runs already)."""
        return self.referee().request("match", action="start")

    def scores(self, team: str = "referee") -> dict[str, Any]:
        """The ``score`` reply: ``teams`` (ranked rows), ``lines`` (the caller's), the clock."""
        c = self._cached(team)
        return c.request("score")

    def score_of(self, team: str) -> float:
        """``team``'s current score."""
        rows = {r["team"]: r for r in self.scores()["teams"]}
        return float(rows[team]["score"])

    def logged_events(self, topic: str | None = None) -> list[dict[str, Any]]:
        """Events the core has written to ``events.log`` so far (optionally of one topic),
        as ``{seq, t, topic, team, data}`` dicts."""
        from robo_comp.core.eventlog import read_log

        path = self.state / "events.log"
        if not path.exists():
            return []
        return [{"seq": r.seq, "t": r.t, "topic": r.topic, "team": r.team, "data": r.data}
                for r in read_log(path, strict=False) if topic is None or r.topic == topic]

    def log_tail(self, name: str = "core.log", chars: int = 3000) -> str:
        """The end of a process log in the state folder (for assertion messages)."""
        p = self.state / name
        return p.read_text(errors="replace")[-chars:] if p.exists() else ""

    def _cached(self, team: str) -> Client:
        for c in self.clients:
            if c.token == self.token(team) and c.sock is not None:
                return c
        return self.client(team)

    def close(self) -> None:
        """Close the clients and stop every process (robot hosts first)."""
        for c in self.clients:
            c.close()
        self.clients.clear()
        stop_all([self.proc, *self.procs])

    def __enter__(self) -> Match:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def start_match(state: Path, scenario: str | os.PathLike[str] | None = DEFAULT_SCENARIO, *,
                teams: Iterable[str] | None = None, practice: bool = True,
                heartbeat: float = HEARTBEAT, extra: Iterable[str] = ()) -> Match:
    """Start a real core process for ``scenario`` with its state in ``state``.

    ``scenario`` is a path or a bundled name (None: the core's built-in arena).
    ``practice=True`` means no phases: the match runs at once and never ends; with False the
    match waits in ``setup`` until :meth:`Match.start`.
    """
    args = ["--heartbeat", str(heartbeat)]
    path = resolve_scenario(scenario) if scenario is not None else None
    if path is not None:
        args += ["--scenario", str(path)]
    if teams:
        args += ["--teams", ",".join(teams)]
    if practice and path is not None:
        args.append("--practice")
    proc = start_core(state, *args, *extra)
    return Match(state, path, proc)


# ---------------------------------------------------------------------- the in-process bench
class TaskError(AssertionError):
    """A team task failed on the bench (``message``, ``reason`` and ``line`` as the sandbox said)."""

    def __init__(self, message: str, reason: str, line: int | None) -> None:
        super().__init__(message)
        self.message = message
        self.reason = reason
        self.line = line


class Bench:
    """Team modules in the real sandbox, robots simulated in-process from a scenario.

    ``Bench(scenario, team, robots=1, seed=0)`` builds the simulated arena (seeded: the scenario's
    seed plus ``seed``), places ``robots`` robots of ``team`` in its start zone (tags 101, 102, ...)
    and starts a :class:`~robo_comp.plugins.sandbox.Sandbox` for them. Nothing moves between robot
    calls: each movement call simulates the arena (steps of ``dt`` seconds) until the movement
    ends, so runs are deterministic.

    What the robot API answers on the bench (``docs/sandbox.md`` lists the calls):

    ===================  =================================================================
    ``move(cells)``      cell by cell along the heading; RobotError at a wall; the believed pose
    ``turn(degrees)``    positive = clockwise on screen (the arena's convention); the pose
    ``go_to(x, y)``      the planned path cell by cell; the pose; RobotError for a wall/no path
    ``position()``       believed ``[x, y, heading]`` (positioning noise and drift included)
    ``sense()``          ``{front, left, right, down (cm or None), bump, moving, zone, time}``
    ``plan(x, y)``       ``[[x, y], ...]`` from the robot's cell; RobotError for a wall/no path
    ``map_piece(r)``     ``{"x0", "y0", "walls"}``: rows of 1 (blocked) / 0, r from 0 to 20
    ``take_picture()``   a picture id (the judge knows what the camera saw)
    ``report_find(...)`` the first 32 evidence ids, judged by the installed scoring rules as
                         the core's ``find``: ``{"id", "state", "message"}``, state
                         ``confirmed``/``rejected``/``duplicate``
    ``radio``, ``upload_picture``  refused (RobotError): no core on the bench
    ===================  =================================================================

    These follow the robot host's answers (``robo_comp/robots/teamcode.py``), which are the
    reference: the bench is for fast, repeatable tests, a real match (:class:`Match`) for the
    final word.
    """

    def __init__(self, scenario: str | os.PathLike[str] | Scenario | None = DEFAULT_SCENARIO,
                 team: str | None = None, *, robots: int = 1, seed: int = 0,
                 limits: Limits | None = None, dt: float = 0.05, max_sim_seconds: float = 600.0) -> None:
        from robo_comp.plugins.manager import get_plugin_manager
        from robo_comp.plugins.sandbox import Sandbox
        from robo_comp.scoring.board import Scoreboard
        from robo_comp.scoring.config import ScoringConfig
        from robo_comp.world.arena import Arena
        from robo_comp.world.localization import Localization
        from robo_comp.world.scenario import Scenario, default_scenario, load_scenario

        if isinstance(scenario, Scenario):
            sc = scenario
        elif scenario is None:
            sc = default_scenario()
        else:
            sc = load_scenario(resolve_scenario(scenario))
        self.scenario = sc
        teams = [t.name for t in sc.teams] or ["red"]
        self.team = team or teams[0]
        if self.team not in teams:
            raise FieldError(f"the scenario has no team {self.team!r}; its teams are {', '.join(teams)}")
        self.arena = Arena(sc, seed=sc.seed + seed, capacity=max(16, robots))
        self.loc = Localization(self.arena)
        self.dt = dt
        self.max_sim_seconds = max_sim_seconds
        cells = self.arena.free_start_cells(self.team)
        if len(cells) < robots:
            raise FieldError(f"team {self.team}'s start zone has room for {len(cells)} robots, not {robots}")
        self.tags = [101 + i for i in range(robots)]
        for tag, (x, y) in zip(self.tags, cells):
            self.arena.add_robot(str(tag), self.team, x, y, 0.0)
        self.loc.update()
        self.board = Scoreboard(teams, get_plugin_manager(), ScoringConfig())
        self.pictures: dict[int, dict[str, Any]] = {}
        self.examined: dict[str, set[int]] = {}
        self.finds: list[dict[str, Any]] = []
        self.calls: list[tuple[int, str, list[Any]]] = []
        self.logs: list[LogLine] = []
        self.sandbox: Sandbox = Sandbox(self.team, self.tags, self._handle, limits, seed=seed)

    # ------------------------------------------------------------------ modules and tasks
    def load(self, path: str | os.PathLike[str], source: str | None = None) -> ModuleInfo:
        """Load a team module (a file, or ``source`` under the file name ``path``) through the
        checked contract; raises :class:`~robo_comp.errors.UploadError` when it is refused."""
        p = Path(path)
        text = p.read_text(encoding="utf-8") if source is None else source
        return self.sandbox.load(p.name, text)

    def tasks(self) -> dict[str, dict[str, Any]]:
        """The tasks the loaded modules advertise (``Sandbox.advertised_tasks``)."""
        return self.sandbox.advertised_tasks()

    def run(self, task: str, *args: Any, tag: int | None = None, timeout: float = 60.0) -> Any:
        """Run ``task(robot, *args)`` on robot ``tag`` (the first robot by default); return its
        result. Raises :class:`TaskError` if the task failed and AssertionError on timeout."""
        from robo_comp.plugins.sandbox import LogLine, TaskDone

        rid = self.sandbox.start_task(self.tags[0] if tag is None else tag, task, list(args))
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            for rec in self.sandbox.poll(0.05):
                if isinstance(rec, LogLine):
                    self.logs.append(rec)
                elif getattr(rec, "run_id", None) == rid:
                    if isinstance(rec, TaskDone):
                        return rec.result
                    raise TaskError(rec.message, rec.reason, rec.line)  # type: ignore[attr-defined]
        self.sandbox.cancel(rid)
        raise AssertionError(f"task {task} did not finish within {timeout} s")

    def log_text(self) -> str:
        """Everything the team code printed or logged, in order."""
        return "".join(line.text for line in self.logs)

    def score(self) -> float:
        """The team's score so far (victims found minus penalties)."""
        return round(sum(ln.points for ln in self.board.lines if ln.team == self.team), 3)

    def true_cell(self, tag: int | None = None) -> tuple[int, int]:
        """Where the robot really is (the arena's ground truth, rounded to a cell)."""
        p = self.arena.pose(str(self.tags[0] if tag is None else tag))
        return int(round(p.x)), int(round(p.y))

    def close(self) -> None:
        """Stop the sandbox process."""
        self.sandbox.close()

    def __enter__(self) -> Bench:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ the robot API
    def _handle(self, tag: int, name: str, args: list[Any]) -> Any:
        self.calls.append((tag, name, list(args)))
        fn = getattr(self, f"_api_{name}", None)
        if fn is None:
            raise UnavailableError(f"the bench does not simulate {name!r} (no core, no radio)")
        return fn(str(tag), *args)

    def _pose(self, t: str) -> list[float]:
        x, y, h = self.loc.estimate(t)
        return [round(float(x), 3), round(float(y), 3), round(float(h) % 360.0, 1)]

    def _cell(self, t: str) -> tuple[int, int]:
        x, y, _ = self.loc.estimate(t)
        return int(round(x)), int(round(y))

    def _drive(self, t: str, kind: str, value: Any) -> None:
        """Command the arena and simulate until the robot stops; RobotError on a bump."""
        self.arena.command(t, kind, value)
        limit = self.arena.time + self.max_sim_seconds
        bump = None
        while True:
            for ev in self.arena.step(self.dt):
                if ev.kind == "bump" and ev.tag == t:
                    bump = ev.data
            self.loc.update()
            if not self.arena.is_moving(t):
                break
            if self.arena.time > limit:
                self.arena.command(t, "halt")
                raise UnavailableError(f"{kind} did not finish within {self.max_sim_seconds:g} simulated s")
        if bump is not None:
            raise UnavailableError(f"bumped into {bump.get('what', 'something')} at "
                                   f"({bump['x']:.1f}, {bump['y']:.1f}) and stopped")

    def _api_move(self, t: str, cells: float) -> list[float]:
        rad = math.radians(self.loc.estimate(t)[2])
        dx, dy = round(math.cos(rad)), round(math.sin(rad))
        if dx and dy:  # between two axes: along the nearer one (as the host does)
            dx, dy = (dx, 0) if abs(math.cos(rad)) >= abs(math.sin(rad)) else (0, dy)
        sign = 1 if cells >= 0 else -1
        h, w = self.arena.walls.shape
        for _ in range(abs(int(cells))):
            x, y = self._cell(t)
            nx, ny = x + sign * dx, y + sign * dy
            if not (0 <= nx < w and 0 <= ny < h) or self.arena.walls[ny, nx]:
                raise BadTaskError(f"({nx}, {ny}) is a wall or outside the arena; stopped at ({x}, {y})")
            self._drive(t, "goto", (nx, ny))
        return self._pose(t)

    def _api_turn(self, t: str, degrees: float) -> list[float]:
        self._drive(t, "turn", degrees)
        return self._pose(t)

    def _path(self, t: str, x: float, y: float) -> list[tuple[int, int]] | None:
        from robo_comp.world.planner import find_path

        gx, gy = int(round(x)), int(round(y))
        h, w = self.arena.walls.shape
        if not (0 <= gx < w and 0 <= gy < h) or self.arena.walls[gy, gx]:
            return None
        sx, sy = self._cell(t)
        sx, sy = min(max(sx, 0), w - 1), min(max(sy, 0), h - 1)
        return find_path(self.arena.walls, (sx, sy), (gx, gy))

    def _checked_path(self, t: str, x: float, y: float) -> list[tuple[int, int]]:
        gx, gy = int(x), int(y)
        h, w = self.arena.walls.shape
        if not (0 <= gx < w and 0 <= gy < h) or self.arena.walls[gy, gx]:
            raise BadTaskError(f"({gx}, {gy}) is a wall or outside the arena")
        path = self._path(t, gx, gy)
        if path is None:
            raise BadTaskError(f"no path to ({gx}, {gy})")
        return path

    def _api_go_to(self, t: str, x: float, y: float) -> list[float]:
        for cx, cy in self._checked_path(t, x, y)[1:]:
            self._drive(t, "goto", (cx, cy))
        return self._pose(t)

    def _api_plan(self, t: str, x: float, y: float) -> list[list[int]]:
        return [[int(cx), int(cy)] for cx, cy in self._checked_path(t, x, y)]

    def _api_position(self, t: str) -> list[float]:
        return self._pose(t)

    def _api_sense(self, t: str) -> dict[str, Any]:
        return {k: _plain(v) for k, v in self.arena.sense(t).items()}

    def _api_map_piece(self, t: str, radius: float) -> dict[str, Any]:
        r = int(radius)
        if not 0 <= r <= MAX_PIECE_RADIUS:
            raise FieldError(f"radius must be between 0 and {MAX_PIECE_RADIUS}")
        x, y = self._cell(t)
        walls = self.arena.walls
        h, w = walls.shape
        rows = [[1 if not (0 <= yy < h and 0 <= xx < w) or walls[yy, xx] else 0
                 for xx in range(x - r, x + r + 1)] for yy in range(y - r, y + r + 1)]
        return {"x0": x - r, "y0": y - r, "walls": rows}

    def _api_take_picture(self, t: str) -> int:
        from robo_comp.world.visibility import in_view

        p = self.arena.pose(t)
        cam = self.scenario.camera
        victims = list(self.arena.victims)
        seen = in_view(self.arena.walls, [(v.x, v.y) for v in victims], p.x, p.y, p.heading, cam.fov, cam.range)
        pid = len(self.pictures) + 1
        ids = [v.id for v, f in zip(victims, seen) if f]
        self.pictures[pid] = {"id": pid, "tag": int(t), "x": p.x, "y": p.y, "heading": p.heading, "victims": ids}
        for vid in ids:
            self.examined.setdefault(vid, set()).add(pid)
        return pid

    def _api_report_find(self, t: str, x: float, y: float, kind: Any, evidence: Any) -> dict[str, Any]:
        ev = [int(e) for e in (evidence or [])][:MAX_EVIDENCE]  # as the host passes it on
        for pid in ev:
            if pid not in self.pictures:
                raise FieldError(f"picture {pid} is not one of team {self.team}'s pictures")
        find = {"team": self.team, "tag": int(t), "x": float(x), "y": float(y), "kind": str(kind or "victim")[:32],
                "evidence": ev}
        victims = [{"id": v.id, "x": v.x, "y": v.y, "kind": v.kind, "points": v.points} for v in self.arena.victims]
        verdict = self.board.judge(find, {"victims": victims, "examined": self.examined})
        fid = len(self.finds) + 1
        state = "confirmed" if verdict["valid"] else ("duplicate" if verdict.get("duplicate") else "rejected")
        self.finds.append(dict(find, id=fid, state=state, verdict=verdict))
        self.board.apply({"kind": "find.judged", "team": self.team, "tag": int(t), "verdict": verdict},
                         self.arena.time)
        return {"id": fid, "state": state, "message": verdict["reason"]}


def _plain(v: Any) -> Any:
    """numpy scalars and other number-likes as plain Python values (msgpack-safe)."""
    if v is None or isinstance(v, (bool, str, int)):
        return v
    if isinstance(v, float):
        return None if math.isnan(v) else v
    if hasattr(v, "item"):
        return _plain(v.item())
    return v


# ---------------------------------------------------------------------- pytest hooks and fixtures
def pytest_addoption(parser: pytest.Parser) -> None:
    """``--robo-scenario`` / ``--robo-team`` and their ini forms."""
    group = parser.getgroup("robo_comp", "robo_comp match and bench fixtures")
    group.addoption("--robo-scenario", default=None,
                    help="scenario file (or bundled scenario name) for robo_match/robo_bench")
    group.addoption("--robo-team", default=None, help="the team robo_bench plays for")
    parser.addini("robo_comp_scenario", "scenario file or bundled name for the robo_comp fixtures",
                  default=DEFAULT_SCENARIO)
    parser.addini("robo_comp_team", "team name for the robo_comp fixtures (default: the scenario's first)",
                  default="")


def pytest_configure(config: pytest.Config) -> None:
    """Register the ``slow`` marker used by team tests that run a real match."""
    config.addinivalue_line("markers", "slow: long-running tests (deselect with -m 'not slow')")


@pytest.fixture(scope="session")
def robo_scenario(pytestconfig: pytest.Config) -> Path:
    """The scenario file the robo_comp fixtures use (see the module docstring)."""
    spec = pytestconfig.getoption("--robo-scenario") or pytestconfig.getini("robo_comp_scenario") or DEFAULT_SCENARIO
    return resolve_scenario(spec, Path(str(pytestconfig.rootpath)))


@pytest.fixture(scope="session")
def robo_team(pytestconfig: pytest.Config, robo_scenario: Path) -> str:
    """The team the tests play for."""
    name = pytestconfig.getoption("--robo-team") or pytestconfig.getini("robo_comp_team")
    if name:
        return str(name)
    from robo_comp.world.scenario import load_scenario

    teams = [t.name for t in load_scenario(robo_scenario).teams]
    return teams[0] if teams else "red"


@pytest.fixture
def robo_match(tmp_path: Path, robo_scenario: Path) -> Iterator[Match]:
    """A real core process serving ``robo_scenario`` in practice mode (stopped at teardown)."""
    m = start_match(tmp_path / "state", robo_scenario)
    try:
        yield m
    finally:
        m.close()


@pytest.fixture
def robo_bench(robo_scenario: Path, robo_team: str) -> Iterator[Bench]:
    """A :class:`Bench` with one robot of ``robo_team`` on ``robo_scenario`` (seed 0)."""
    b = Bench(robo_scenario, robo_team)
    try:
        yield b
    finally:
        b.close()


__all__ = ["Bench", "DEFAULT_SCENARIO", "Match", "TaskError", "next_event_where", "resolve_scenario",
           "start_match", "wait_for", "wait_robots"]
