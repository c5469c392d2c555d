"""A manifest with an unknown key."""
# expect: upload
# match: manifest: MANIFEST: unknown key\(s\) permissions
MANIFEST = {"name": "hostile", "version": "1", "kind": "extension", "permissions": "root",
            "tasks": {"attack": {"args": []}}}

def attack(robot):
    return 1
