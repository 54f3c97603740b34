"""The route of a tendon across rods welded together (``[[tendons]]`` with ``to_rod``):
plain Python at scene parse time, errors naming the key path.

The rods are the vertices of a graph whose edges are the welds between nodes of two
different rods (ball joints and joints to bodies are not crossed). A tendon starting on
rod ``rod`` and terminated on rod ``to_rod`` follows the one simple path of welds
between them: on each rod it runs from the node where it enters (``from_node`` on the
first rod, the weld's node otherwise) to the node where it leaves (the next weld's node,
``to_node`` on the last rod). Rods joined by no path of welds, or by more than one (a
loop of welds), are refused. That the routing meets itself at each weld is checked when
the scene is read (:mod:`simsoft_jax.scene.scene_start`).
"""
from __future__ import annotations

from .key_checks import fail, join


def _weld_edges(joints: tuple) -> dict:
    """rod name -> [(joint index, node on this rod, other rod, node on the other rod)]."""
    edges: dict = {}
    for i, j in enumerate(joints):
        a, b = j.a, j.b
        if j.kind != "weld" or a.rod is None or b.rod is None or a.rod == b.rod:
            continue
        edges.setdefault(a.rod, []).append((i, a.node, b.rod, b.node))
        edges.setdefault(b.rod, []).append((i, b.node, a.rod, a.node))
    return edges


def weld_path(start: str, end: str, joints: tuple, path: str) -> tuple:
    """The welds a tendon crosses from rod ``start`` to rod ``end``, in order: a tuple of
    ``(joint index, node on the rod before, rod after, node on the rod after)`` (empty
    when start is end). ``path`` is the tendon's key path, for errors."""
    edges, found = _weld_edges(joints), []

    def walk(rod, visited, steps):
        if rod == end:
            found.append(tuple(steps))
            return
        for step in edges.get(rod, ()):
            if step[2] not in visited and len(found) < 2:
                walk(step[2], visited | {step[2]}, steps + [step])

    walk(start, {start}, [])
    if not found:
        fail(join(path, "to_rod"), f"no path of welds from rod {start!r} to rod {end!r} (a "
             "tendon crosses from rod to rod only at welds between two rod nodes)")
    if len(found) > 1:
        routes = [" -> ".join(f"joints[{step[0]}]" for step in route) for route in found]
        fail(join(path, "to_rod"), f"more than one path of welds from rod {start!r} to rod "
             f"{end!r} ({routes[0]}; {routes[1]}): a tendon's route must be unique")
    return found[0]
