"""A "code" upload that replaces the behaviour of the built-in goTo task.

The thesis's executeCode example replaced the robot's doTask() at run time; here the same idea is
a module of kind "code" declaring a task with a built-in name. The host decides whether the
uploaded goTo takes precedence over its own (the sandbox reports ``replaces_builtin``).

This goTo logs, wanders via a detour point half-way (offset sideways by ``detour`` cells when the
map allows it), and then delegates to the robot's own path-planned ``go_to``.
"""

MANIFEST = {
    "name": "wander",
    "version": "1.0",
    "kind": "code",
    "description": "goTo via a sideways detour, for exploring on the way.",
    "tasks": {
        "goTo": {
            "description": "Go to (x, y), wandering via a detour point half-way.",
            "args": [
                {"name": "x", "type": "int", "description": "target column"},
                {"name": "y", "type": "int", "description": "target row"},
            ],
        },
    },
}

DETOUR = 2


def goTo(robot, x, y):
    here = robot.position()
    mx = (here[0] + x) // 2
    my = (here[1] + y) // 2 + DETOUR
    robot.log(f"wander: from {here[0]},{here[1]} via {mx},{my} to {x},{y}")
    try:
        robot.go_to(mx, my)
    except RobotError as exc:
        robot.log(f"wander: detour refused ({exc}); going straight")
    robot.go_to(x, y)
    return robot.position()
