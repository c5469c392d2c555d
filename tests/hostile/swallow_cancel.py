"""Keep looping after the task is cancelled (catches TaskCancelled)."""
# expect: run
# match: (did not stop within .* of being cancelled|CPU time limit \(1 s\) exceeded)
# cancel-after: 0.3
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    while True:
        try:
            robot.sense()
        except BaseException:
            pass
