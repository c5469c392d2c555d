"""Call the robot API for a robot the team was not given (via radio to a forged object)."""
# expect: run
# match: (read-only|RobotError)
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    robot.tag = 999
    return robot.move(1)
