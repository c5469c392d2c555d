"""from os import system inside a task."""
# expect: run
# match: import of 'os' is not allowed
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    from os import system
    system('touch /tmp/robo_comp_pwned')
