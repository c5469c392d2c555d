"""Walk from an exception to its context, frames and the sandbox's internals."""
# expect: run
# match: "__context__" is an invalid attribute name
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}


def attack(robot):
    try:
        robot.no_such_call()
    except AttributeError as e:
        ctx = getattr(e, "__con" + "text__")
        return ctx
