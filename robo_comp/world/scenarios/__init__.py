"""Bundled scenario files (``*.toml``) and their maps; see docs/scenarios.md.

A package only so that the files are installed with robo_comp; use
:func:`robo_comp.world.scenario.bundled_scenario_path` to find one.
"""
