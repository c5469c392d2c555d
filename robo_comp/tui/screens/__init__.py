"""Screens of the team and referee consoles."""
