"""robo_comp.tui: the Textual team console and referee console (see docs/consoles.md).

``robo-comp team`` runs :class:`robo_comp.tui.team_app.TeamApp`; ``robo-comp referee`` runs
:class:`robo_comp.tui.referee_app.RefereeApp`; :mod:`robo_comp.tui.cli` adds both subcommands.
"""
