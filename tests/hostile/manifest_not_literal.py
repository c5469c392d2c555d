"""MANIFEST built by code instead of a literal."""
# expect: upload
# match: manifest: MANIFEST must be a literal dict
MANIFEST = dict(name="hostile", version="1", kind="extension", tasks={})

def attack(robot):
    return 1
