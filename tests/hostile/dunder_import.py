"""Call __import__ directly."""
# expect: upload
# match: policy: .*\(`__import__`\) are kept for Python itself
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return __import__('os').system('id')
