"""Read /etc/passwd with open()."""
# expect: run
# match: NameError: name 'open' is not defined
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return open('/etc/passwd').read()
