"""print() in a loop, swallowing the output-limit error."""
# expect: run
# match: output limit \(\d+ KiB\) exceeded
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    while True:
        try:
            robot.log('spam ' * 50)
        except BaseException:
            pass
