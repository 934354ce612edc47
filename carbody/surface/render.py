"""Three-view shaded picture of a surfaced body (delegates to :mod:`carbody.render`, VTK off-screen)."""
from __future__ import annotations

from pathlib import Path

from carbody.surface.body import Body, region_colour


def render_body(body: Body, path: str | Path, size: tuple[int, int] = (480, 340)) -> Path:
    """Render ``body`` from front 30°, the side and rear 30°, faces in their region colours."""
    from carbody.render import render_views

    colours = {name: region_colour(name) for name in {n for n, _ in body.faces}}
    render_views(body, path, size=size, colours=colours)
    return Path(path)
