"""Exports of a match to other tools' formats (``robo-comp export``)."""
