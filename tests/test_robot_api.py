"""The robot API is defined once (robo_comp/sandbox/api.py): the sandbox child builds the robot
object from it, and the host's and the engine's call table answers exactly its remote calls."""
from __future__ import annotations

from robo_comp.engine import Bench, TaskError
from robo_comp.robots import teamcode
from robo_comp.sandbox import api

import pytest

PROBE = ('MANIFEST = {"name": "probe", "version": "1", "kind": "extension", "tasks": {"names": {"args": []}, '
         '"bad_move": {"args": []}, "bad_go": {"args": []}}}\n\n'
         'def names(robot):\n    return sorted(n for n in ' + repr([c.name for c in api.ROBOT_API]) +
         ' if hasattr(robot, n))\n\n'
         'def bad_move(robot):\n    robot.move()\n\n'
         'def bad_go(robot):\n    robot.go_to("here", 3)\n')


def test_the_call_table_answers_exactly_the_api_s_remote_calls():
    answered = set(teamcode.ROBOT_CALLS) - {"draw"}  # the frames debug drawing sends (not a robot call)
    assert answered == set(api.REMOTE) - set(api.MOVEMENTS)
    assert set(teamcode.MOVEMENT_CALLS) == set(api.MOVEMENTS) == {"move", "turn", "go_to"}
    assert "x y" in " ".join(api.BY_NAME["go_to"].params) and api.BY_NAME["go_to"].numbers == {"x", "y"}


def test_the_sandboxed_robot_has_every_call_with_python_s_own_checks():
    with Bench("demo_room", "red") as bench:
        bench.load("probe.py", PROBE)
        assert bench.run("names") == sorted(c.name for c in api.ROBOT_API)
        with pytest.raises(TaskError, match=r"move\(\) missing 1 required positional argument: 'cells'"):
            bench.run("bad_move")
        with pytest.raises(TaskError, match="x must be a number"):
            bench.run("bad_go")
