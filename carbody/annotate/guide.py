"""Which keypoint the page asks for next.

Before the car is fitted the page knows only the view (the classifier's guess or the one the user
picked): it asks the keypoints that view shows on the library's mean car, spread over the car as
far as they go (farthest-point order in the picture), so the first five already pin the photo's
scale, offset and view. Once the car is fitted it asks the keypoint the fit is least sure of in
the photo (its ghost's expected error, pixels): a mark there teaches the fit the most, and the
ghosts it is sure of can be accepted with one key.

(Asking the near side's keypoints before the far side's was tried: it made no difference to the
real photos' skipped keypoints and took the example from 8 to 23 actions to the hand-marked
fit, ``benchmarks/bench_annotate.py``.)
"""
from __future__ import annotations

import functools

import numpy as np

from carbody.camera import View, project


@functools.cache
def reference_car() -> np.ndarray:
    """(280, 3) the library's mean car, normalised units: the car the page draws before a fit."""
    from carbody.library import default_library

    return default_library().S.mean(axis=1).reshape(-1, 3)


def reference_keypoints(control_points: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """{name: (3,)} of every markable name (both halves) on ``control_points`` (default the
    reference car)."""
    from carbody.fit import keypoint_slots

    cp = reference_car() if control_points is None else control_points
    return {name: cp[s.point_index] * s.sign for name, s in keypoint_slots().items()}


def spread_order(view: View, names: list[str], placed: dict[str, tuple[float, float]] | None = None) -> list[str]:
    """``names`` in farthest-point order on the reference car seen from ``view``: each next one
    the farthest (in the picture) from those before it and from the keypoints already
    ``placed``; with nothing placed, the farthest from the car's centre first."""
    if not names:
        return []
    points = reference_keypoints()
    uv = {n: project(p, view) for n, p in points.items()}
    chosen = [uv[n] for n in (placed or {}) if n in uv]  # (the reference car's, not the marks')
    left, order = list(names), []
    if not chosen:
        centre = np.mean([uv[n] for n in points], axis=0)
        first = max(left, key=lambda n: float(np.linalg.norm(uv[n] - centre)))
        order.append(first)
        chosen.append(uv[first])
        left.remove(first)
    while left:
        taken = np.array(chosen)
        nxt = max(left, key=lambda n: float(np.min(np.linalg.norm(taken - uv[n], axis=1))))
        order.append(nxt)
        chosen.append(uv[nxt])
        left.remove(nxt)
    return order


def shown_names(view: View) -> list[str]:
    """The names the reference car shows from ``view`` (both halves, id order)."""
    from carbody.fit import visible_keypoints

    return visible_keypoints(view, reference_car())


def ask_order(view: View, marks: dict, hidden: set[str], ghosts: dict[str, dict] | None = None) -> list[str]:
    """The keypoints to ask for, first first: unmarked and not hidden.

    Args:
        view: the fitted view, or the guessed one before a fit.
        marks: {name: (u, v)} placed so far.
        hidden: names the user said the photo does not show.
        ghosts: the fit's ghosts ({name: {"uv", "sd_px"}}, :func:`~carbody.annotate.live_fit.fit_payload`),
            or None before a fit.
    """
    if ghosts:
        left = [n for n in ghosts if n not in marks and n not in hidden]
        return sorted(left, key=lambda n: -ghosts[n]["sd_px"])
    left = [n for n in shown_names(view) if n not in marks and n not in hidden]
    return spread_order(view, left, dict(marks))
