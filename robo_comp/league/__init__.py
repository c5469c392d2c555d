"""The league: submissions, schedules, ratings and runners for many matches (docs/league.md).

* :mod:`~robo_comp.league.store` — the league's state in SQLite (submissions, matches, ratings);
* :mod:`~robo_comp.league.engine` — one match, played by the official engine (the bench);
* :mod:`~robo_comp.league.schedule` — the formats (scrimmage, round robin, Swiss, double elimination);
* :mod:`~robo_comp.league.ratings` — openskill (Plackett–Luce), leaderboard by μ − 3σ;
* :mod:`~robo_comp.league.runner` — local processes or a Ray cluster;
* :mod:`~robo_comp.league.season` — the pieces together; :mod:`~robo_comp.league.cli` its commands;
* :mod:`~robo_comp.league.report` — the table and the HTML report;
* :mod:`~robo_comp.league.reference` — the reference teams.
"""
