"""Call __import__ directly."""
# expect: upload
# match: policy: .*"__import__" is an invalid variable name
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return __import__('os').system('id')
