"""What people look at: the standings as text and the league as one static HTML page.

Both take the league as plain data (:func:`robo_comp.league.season.league_view`), so they work
from a ``league table --json`` dump as well as from the store. Team names come from users:
everything shown is escaped.
"""
from __future__ import annotations

import html
import io
from pathlib import Path
from typing import Any

from robo_comp.private_files import write_private

COLUMNS = ("rank", "team", "version", "rating", "mu", "sigma", "matches", "wins", "mean_score")
HEADINGS = ("#", "team", "version", "rating (μ−3σ)", "μ", "σ", "matches", "wins", "mean score")


def _cell(row: dict[str, Any], key: str) -> str:
    v = row.get(key)
    if key == "rating" and v is not None and row.get("provisional"):
        return f"{v:.2f} ?"  # provisional: σ still above ratings.SURE_SIGMA
    if v is None:
        return "–"
    if isinstance(v, float):
        return f"{v:.2f}"
    return str(v)


def standings_text(view: dict[str, Any], width: int = 120) -> str:
    """The leaderboard as a text table (what ``robo-comp league table`` prints)."""
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    played = sum(1 for m in view["matches"] if m.get("status") == "done")
    table = Table(title=f"{view['name']}: {played} matches played", title_justify="left")
    for h in HEADINGS:
        table.add_column(h, justify="left" if h in ("team", "version") else "right", no_wrap=h in ("team", "version"))
    for row in view["standings"]:
        table.add_row(*(Text(_cell(row, k)) for k in COLUMNS))  # Text: a team name is never markup
    console = Console(file=io.StringIO(), width=width, record=True, color_system=None)
    console.print(table)
    text = console.export_text().rstrip()
    notes = [n for n in (provisional_text(view), held_text(view)) if n]
    return "\n".join([text, *notes])


def provisional_text(view: dict[str, Any]) -> str:
    """The sentence under a table with provisional ratings."""
    from robo_comp.league.ratings import SURE_SIGMA

    if not any(r.get("provisional") for r in view["standings"]):
        return ""
    return (f"? provisional: σ ≥ {SURE_SIGMA:g}, too few matches to trust the rank "
            "(μ: the rating, σ: how unsure it is; the table orders by μ − 3σ).")


def held_text(view: dict[str, Any]) -> str:
    """A sentence when a match that is not played holds up the ratings of played ones."""
    held = view.get("held")
    if not held:
        return ""
    why = f" ({held['error'].strip().splitlines()[-1][:120]})" if held.get("error") else ""
    return (f"Ratings wait for match {held['match']}, {held['status']}{why}: {held['waiting']} played "
            f"match(es) behind it are not rated yet. 'robo-comp league run' plays it again; "
            f"'robo-comp league cancel LEAGUE {held['match']}' takes it out.")


def _svg(fig: Any) -> str:
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight")
    text = buf.getvalue()
    return text[text.index("<svg"):]  # without the XML prolog and doctype: inline in the page


def rating_plot(view: dict[str, Any]) -> str:
    """Each team's rating (μ − 3σ) after each ranked match, as inline SVG."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from robo_comp.scoring.results import team_colours

    fig = Figure(figsize=(8, 4))
    ax = fig.subplots()
    colours = team_colours([row["team"] for row in view["standings"]])  # one each: no repeats past 10 teams
    for i, row in enumerate(view["standings"]):
        points = view["history"].get(row["team"], [])
        if points:
            ax.plot([p[0] for p in points], [p[1] for p in points], marker=".", linewidth=1, label=row["team"],
                    color="#%02x%02x%02x" % colours[row["team"]], linestyle=("-", "--", ":")[i // 10 % 3])
    ax.set_xlabel("ranked match")
    ax.set_ylabel("rating (μ − 3σ)")
    ax.grid(alpha=0.3)
    if ax.get_lines() and len(view["standings"]) <= 16:
        ax.legend(fontsize=7, ncol=2, loc="best")
    return _svg(fig)


def score_plot(scenario: str, scores: dict[str, list[float]], order: list[str]) -> str:
    """Score distributions of the teams on one scenario (box plots), as inline SVG."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    teams = [t for t in order if t in scores] + sorted(t for t in scores if t not in order)
    fig = Figure(figsize=(max(4.0, 0.6 * len(teams) + 2), 3.2))
    ax = fig.subplots()
    ax.boxplot([scores[t] for t in teams], showmeans=True)
    ax.set_xticks(range(1, len(teams) + 1), teams, rotation=45, ha="right", fontsize=8)
    ax.set_title(scenario, fontsize=10)
    ax.set_ylabel("score")
    ax.grid(alpha=0.3, axis="y")
    return _svg(fig)


STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em; color: #222; }
table { border-collapse: collapse; margin: 1em 0; }
th, td { padding: 0.25em 0.7em; border-bottom: 1px solid #ddd; text-align: right; }
th { background: #f3f3f3; }
td.name, th.name { text-align: left; }
.plots { display: flex; flex-wrap: wrap; gap: 1em; }
.hint { color: #555; font-size: 0.9em; }
"""


def render_report(view: dict[str, Any]) -> str:
    """The league as one self-contained HTML page (plots inline as SVG)."""
    e = html.escape
    order = [r["team"] for r in view["standings"]]
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>{e(view['name'])}</title>"
             f"<style>{STYLE}</style></head><body>",
             f"<h1>{e(view['name'])}</h1><p class='hint'>generated {e(view['generated'])}</p>",
             "<h2>Standings</h2><table><tr>"
             + "".join(f"<th class='{'name' if h in ('team', 'version') else ''}'>{e(h)}</th>" for h in HEADINGS)
             + "</tr>"]
    for row in view["standings"]:
        parts.append("<tr>" + "".join(
            f"<td class='{'name' if k in ('team', 'version') else ''}'>{e(_cell(row, k))}</td>" for k in COLUMNS)
            + "</tr>")
    parts.append("</table>")
    if provisional_text(view):
        parts.append(f"<p class='hint'>{e(provisional_text(view))}</p>")
    if view.get("held"):
        parts.append(f"<p class='hint'>{e(held_text(view))}</p>")
    played = [m for m in view["matches"] if m.get("status") == "done"]
    if not played:
        parts.append("<p>No matches played yet.</p></body></html>")
        return "".join(parts)
    parts.append("<h2>Ratings over the season</h2>" + rating_plot(view))
    parts.append("<h2>Scores per scenario</h2><div class='plots'>")
    for scenario in sorted(view["scores"]):
        parts.append(f"<div>{score_plot(scenario, view['scores'][scenario], order)}</div>")
    parts.append("</div>")
    parts.append("<h2>Matches</h2><p class='hint'>Watch a match again in a browser with the command in its "
                 "row (<code>robo-comp web --replay LOG</code>, run in this page's folder), or feed the wall and the consoles with "
                 "<code>robo-comp replay LOG</code>. A log is a binary event log, not a page.</p><table><tr>"
                 "<th>match</th><th class='name'>format</th><th>round</th><th class='name'>scenario</th>"
                 "<th>seed</th><th class='name'>ranked</th><th class='name'>teams (score)</th><th>log</th>"
                 "<th class='name'>limits</th></tr>")
    for m in view["matches"]:
        teams = ", ".join(f"{e(t)} ({m['scores'][t]:g})" if t in m.get("scores", {}) else e(t) for t in m["teams"])
        link = (f"<code>robo-comp web --replay {e(m['log'])}</code>" if m.get("status") == "done"
                else e(m["status"]))
        parts.append(f"<tr><td>{m['id']}</td><td class='name'>{e(m['format'])}</td><td>{m['round']}</td>"
                     f"<td class='name'>{e(m['scenario'])}</td><td>{m['seed']}</td>"
                     f"<td class='name'>{'yes' if m['ranked'] else 'test'}</td><td class='name'>{teams}</td>"
                     f"<td>{link}</td><td class='name'>{'<br>'.join(e(n) for n in m.get('notes', []))}</td></tr>")
    parts.append("</table>")
    crashed = [m for m in view["matches"] if m.get("crashes")]
    if crashed:
        from robo_comp.league.forensics import crash_text, rerun_command

        parts.append("<h2>Where team code crashed</h2><p class='hint'>The robot, its last robot call, the line "
                     "and the traceback through the team's files, the match time and the seed; the command "
                     "plays that match again on your machine (the same crash: league matches are "
                     "deterministic). Add <code>--team TEAM=PATH</code> to play your edited folder instead.</p>")
        for m in crashed:
            command = rerun_command(view.get("root", "LEAGUE"), m["id"])
            text = "\n".join(crash_text(c, seed=m["seed"], scenario=m["scenario"], command=command)
                             for c in m["crashes"])
            parts.append(f"<h3>match {m['id']}</h3><pre>{e(text)}</pre>")
    parts.append("</body></html>")
    return "".join(parts)


def write_report(path: str | Path, view: dict[str, Any]) -> Path:
    """Write :func:`render_report`'s page to ``path``; returns the path."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    return write_private(p, render_report(view))  # 0600: the organiser publishes it, not the umask


__all__ = ["held_text", "provisional_text", "render_report", "standings_text", "write_report"]
