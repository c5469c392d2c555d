"""What every viewer of a match shares: one read-side fold of its events, with no UI.

The wall (pygame), the web page (its gateway and its replays) and the tests read a match through
the same model: :class:`~robo_comp.view.model.MatchView` applies the core's events (live, from a
snapshot and the feed, or from a recorded log), :class:`~robo_comp.view.score.ScoreFold` folds a
log's score lines, and :mod:`~robo_comp.view.colours` colours the map the same way everywhere.
No viewer imports another viewer.
"""
