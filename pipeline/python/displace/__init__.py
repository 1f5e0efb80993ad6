"""displace: dynamic height fields with per-pixel displacement mapping, from Python.

Scenes, heights, cone maps, height queries and rendered frames as numpy arrays, the same numbers as
the `displace` command's (sim, bake, query, sequence). Units: metres and seconds; cone ratios and
[0, 1] heights as bake/bake.h defines them. In full: docs/python.md.

    >>> import displace
    >>> scene = displace.Scene.builtin("water")
    >>> displace.query(scene, 2.0, [[10.0, 20.0]])["height_m"]
"""
from ._displace import Pipeline, Scene, bake, heights, query

__all__ = ["Pipeline", "Scene", "bake", "heights", "query"]


def _frames(self, first=0, count=None):
    """Yields (n, frame) for frames first, first + 1, ... (count of them; None: without end)."""
    n = first
    while count is None or n < first + count:
        yield n, self.frame(n)
        n += 1


Pipeline.frames = _frames
