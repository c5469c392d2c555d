"""The referee console: ``robo-comp referee --core URL --token R``.

The whole match on one screen: phase control (start, pause/resume, finish, extend) with
confirmations, every team's score, every robot, penalties with reasons, disqualification,
broadcasts to all consoles, approval of uploads, and the event log with filters.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from functools import partial
from pathlib import Path
from typing import Any

from textual.binding import Binding
from textual.screen import Screen

from robo_comp.errors import RoboCompError

from robo_comp.tui.app import ConsoleApp
from robo_comp.tui.screens.confirm import ConfirmScreen
from robo_comp.tui.screens.forms import Field, FormScreen
from robo_comp.tui.model import LogEntry
from robo_comp.tui.screens.leaderboard import LeaderboardScreen
from robo_comp.tui.screens.recovery import RecoveryScreen
from robo_comp.tui.screens.referee import RefereeScreen
from robo_comp.tui.widgets.core_line import lost_summary
from robo_comp.tui.widgets.score import ScoreTable

PHASE_QUESTIONS = {
    "start": "Start the match now? Teams may give tasks from this moment.",
    "pause": "Pause the match? Every robot holds until you resume.",
    "resume": "Resume the match? Robots move again and the clock runs.",
    "finish": "FINISH the match now? Results are frozen; this cannot be undone.",
}


class RefereeApp(ConsoleApp):
    """The referee's console."""

    TITLE = "robo_comp referee console"
    BINDINGS = [
        Binding("ctrl+s", "stop", "STOP", priority=True, tooltip="Halt the selected robot at once"),
        Binding("ctrl+x", "stop_all", "STOP ALL", priority=True, show=False, tooltip="Halt every robot"),
    ]
    CLIENT_NAME = "referee-console"

    def __init__(self, *args: Any, league: str | Path | None = None, **kwargs: Any) -> None:
        """As :class:`ConsoleApp`; ``league`` is a league folder whose leaderboard ``l`` shows."""
        super().__init__(*args, **kwargs)
        self.league = Path(league) if league is not None else None
        self._told_recovery = ""

    def main_screen(self) -> Screen[Any]:
        return RefereeScreen(self.model)

    # ------------------------------------------------------------------ the league
    def league_view(self) -> dict[str, Any] | None:
        """The league's standings and matches as plain data (None without ``--league``)."""
        if self.league is None:
            return None
        from robo_comp.league.season import league_view
        from robo_comp.league.store import LeagueStore

        with LeagueStore(self.league) as store:
            return league_view(store)

    def action_leaderboard(self) -> None:
        """Show the league's leaderboard (``--league``)."""
        try:
            view = self.league_view()
        except RoboCompError as e:
            self.notify(e.message, title="League", severity="error")
            return
        if view is None:
            self.notify("start the console with --league LEAGUE to see a league's leaderboard", title="League")
            return
        self.push_screen(LeaderboardScreen(view))

    def on_leaderboard_screen_refresh_requested(self, message: LeaderboardScreen.RefreshRequested) -> None:
        """Read the league again and show it."""
        view = self.league_view()
        if view is not None and isinstance(self.screen, LeaderboardScreen):
            self.screen.update_view(view)
            self.notify("leaderboard read again", title="League")

    # ------------------------------------------------------------------ phases
    def action_match(self, action: str) -> None:
        """Change the phase after a confirmation."""
        self.push_screen(ConfirmScreen(PHASE_QUESTIONS[action], yes=action.capitalize(), danger=action == "finish"),
                         partial(self._confirmed_match, action))

    def action_pause_resume(self) -> None:
        """Pause a running match, resume a paused one."""
        self.action_match("resume" if self.model.match.phase == "paused" else "pause")

    def _confirmed_match(self, action: str, yes: bool | None) -> None:
        if yes:
            self.spawn(self.match(action), group="match")

    async def match(self, action: str, seconds: float | None = None) -> dict[str, Any] | None:
        """Send a ``match`` request; the phase shows when the reply (and the event) arrive."""
        body: dict[str, Any] = {"action": action}
        if seconds is not None:
            body["seconds"] = seconds
        reply = await self.call("match", title=f"Cannot {action} the match", **body)
        if reply is not None:
            self.model.set_match(reply)
        return reply

    # ------------------------------------------------------------------ the core: outage rule, recovery
    def action_outage(self) -> None:
        """Choose what a core outage (a crash, a restart) does to the match clock."""
        self.push_screen(FormScreen("What a core outage does to the match clock", [
            Field("rule", "While no core runs (a crash, a restart), the match clock…", "select",
                  [("pause: stands still (the outage is not match time)", "pause"),
                   ("count: runs on (the outage is match time)", "count")], value=self.model.outage or "pause")],
            "Set the rule"), self._outage_done)

    def _outage_done(self, values: dict[str, Any] | None) -> None:
        if values:
            self.spawn(self.set_outage(str(values["rule"])), group="match")

    async def set_outage(self, rule: str) -> dict[str, Any] | None:
        """The ``match`` request with action ``outage`` (as ``ctl match outage --rule``)."""
        reply = await self.call("match", title="Cannot change the outage rule", action="outage", rule=rule)
        if reply is not None:
            self.model.set_match(reply)
        return reply

    def action_recovery(self) -> None:
        """Show what the core recovered from its event log when it started."""
        self.push_screen(RecoveryScreen(self.model.recovered, self.model.recovery_known, self.model.outage))

    async def reload(self) -> None:
        """Everything after (re)connecting, and what this core recovered from its log (``stats``)."""
        await super().reload()
        stats = await self.call("stats", quiet=True)
        if stats is not None:
            self.model.set_recovery(stats.get("recovered"))
            self.tell_recovery()
            self._redraw(force=True)

    def tell_recovery(self) -> None:
        """A toast that stays a while when the core's log lost events (once per report)."""
        rec = self.model.recovered
        lost = lost_summary(rec, named=8)
        key = repr(sorted((rec or {}).items()))
        if not lost or key == self._told_recovery:
            return
        self._told_recovery = key
        self.notify(f"{lost}. Press r for the report.", title="⚠ The core's event log was damaged",
                    severity="error", timeout=60)

    def toast(self, e: LogEntry) -> None:
        super().toast(e)
        if e.topic == "core.recovered":
            self.tell_recovery()

    def action_extend(self) -> None:
        self.push_screen(FormScreen("Extend the match", [Field("seconds", "Seconds to add", "number", value=60)],
                                    "Extend"), self._extend_done)

    def _extend_done(self, values: dict[str, Any] | None) -> None:
        if values:
            self.spawn(self.match("extend", float(values["seconds"])), group="match")

    # ------------------------------------------------------------------ referee powers
    def _team_options(self) -> list[tuple[str, str]]:
        return [(t, t) for t in self.model.teams]

    def _selected_team(self) -> str | None:
        try:
            return self.screen_stack[1].query_one(ScoreTable).selected_team
        except Exception:
            return None

    def action_penalty(self) -> None:
        """Give a team a penalty (points and a reason the team sees)."""
        self.push_screen(FormScreen("Penalty", [
            Field("team", "Team", "select", self._team_options(), value=self._selected_team()),
            Field("points", "Points (negative takes points away)", "number", value=-10),
            Field("reason", "Reason (the team sees it)")], "Give penalty", danger=True), self._penalty_done)

    def _penalty_done(self, values: dict[str, Any] | None) -> None:
        if values:
            self.spawn(self._request("penalty", f"Penalty for {values['team']}", team=values["team"],
                                          points=values["points"], reason=values["reason"]))

    def action_disqualify(self) -> None:
        """Disqualify the selected robot or a whole team, with a reason."""
        targets: list[tuple[str, str]] = []
        if self.selected is not None:
            targets.append((f"robot {self.selected} ({self.model.robots.get(self.selected, {}).get('team', '?')})",
                            f"tag:{self.selected}"))
        targets += [(f"team {t} (all its robots)", f"team:{t}") for t in self.model.teams]
        self.push_screen(FormScreen("Disqualify", [
            Field("target", "Who", "select", targets, value=targets[0][1] if targets else None),
            Field("reason", "Reason")], "Disqualify", danger=True), self._disqualify_form_done)

    def _disqualify_form_done(self, values: dict[str, Any] | None) -> None:
        if not values:
            return
        kind, _, name = str(values["target"]).partition(":")
        body: dict[str, Any] = {"reason": values["reason"]}
        if kind == "tag":
            body["tag"] = int(name)
        else:
            body["team"] = name
        self.push_screen(ConfirmScreen(f"Disqualify {kind if kind == 'team' else 'robot'} {name}? "
                                       "This cannot be undone.", yes="Disqualify", danger=True),
                         partial(self._disqualify_confirmed, body))

    def _disqualify_confirmed(self, body: dict[str, Any], yes: bool | None) -> None:
        if yes:
            self.spawn(self._request("disqualify", "Disqualified", **body))

    def action_broadcast(self) -> None:
        """Send a message to every console."""
        self.push_screen(FormScreen("Broadcast to every console", [Field("message", "Message")], "Send"),
                         self._broadcast_done)

    def _broadcast_done(self, values: dict[str, Any] | None) -> None:
        if values:
            self.spawn(self._request("broadcast", "Broadcast", message=values["message"]))

    def action_approve(self) -> None:
        """Approve or reject a pending upload."""
        pending = self.model.pending_uploads
        if not pending:
            self.notify("no upload waits for approval", title="Approve")
            return
        opts = [(f"#{uid} {p.get('team')}: {p.get('filename')}", uid) for uid, p in pending.items()]
        self.push_screen(FormScreen("Approve an upload", [
            Field("upload_id", "Upload", "select", opts, value=opts[0][1]),
            Field("ok", "Decision", "select", [("approve", True), ("reject", False)], value=True)], "Decide"),
            self._approve_done)

    def _approve_done(self, values: dict[str, Any] | None) -> None:
        if values:
            self.model.pending_uploads.pop(values["upload_id"], None)
            self.spawn(self._request("approve", "Upload decided", upload_id=values["upload_id"],
                                          ok=bool(values["ok"])))

    async def _request(self, type_: str, done_title: str, **body: Any) -> dict[str, Any] | None:
        reply = await self.call(type_, **body)
        if reply is not None:
            self.notify("done", title=done_title)
            if "teams" in reply:
                self.model.set_scores(reply["teams"])
        return reply

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        needs = {"match": "match", "pause_resume": "match", "extend": "match", "outage": "match", "penalty": "penalty",
                 "disqualify": "disqualify", "broadcast": "broadcast", "approve": "approve"}
        if action in needs:
            return self.feature(needs[action])
        return True

    # ------------------------------------------------------------------ palette
    def robot_commands(self, tag: int) -> list[tuple[str, str, Callable[[], Any]]]:
        return [(f"Disqualify robot {tag}", "with a reason, after a confirmation",
                 partial(self._palette_disqualify, tag))]

    def _palette_disqualify(self, tag: int) -> None:
        self.select_robot(tag)
        self.action_disqualify()

    def console_commands(self) -> Iterable[tuple[str, str, Callable[[], Any]]]:
        yield from super().console_commands()
        yield "Start the match", "setup → running (g)", partial(self.action_match, "start")
        yield "Pause or resume the match", "(p)", self.action_pause_resume
        yield "Finish the match", "results are frozen (f)", partial(self.action_match, "finish")
        yield "Extend the match", "add seconds (e)", self.action_extend
        yield "Outage rule", "what a core outage does to the match clock: pause or count (o)", self.action_outage
        yield "Recovery report", "what the core recovered from its log: damage, lost events (r)", self.action_recovery
        yield "Give a penalty", "points and a reason (n)", self.action_penalty
        yield "Disqualify", "a robot or a team (d)", self.action_disqualify
        yield "Broadcast", "a message to every console (b)", self.action_broadcast
        yield "Approve an upload", "(a)", self.action_approve
        yield "League leaderboard", "the --league standings (l)", self.action_leaderboard
