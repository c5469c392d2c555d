"""from os import system inside a task: refused at upload (every import is read, not only those
that run when the module loads)."""
# expect: upload
# match: policy: import of 'os' is not allowed
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    from os import system
    system('touch /tmp/robo_comp_pwned')
