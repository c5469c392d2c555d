"""Widgets of the team and referee consoles."""
