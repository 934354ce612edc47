"""Which keypoint the page asks for next.

Every keypoint the page asks for costs the user a key press, even one the photo does not show
clearly (H).

- **Before the car is fitted** the page knows only the view (the classifier's guess or the one
  the user picked): it asks first the keypoints that view shows squarely on the library's mean
  car even if the guess is :data:`GUESS_SPREAD_DEG` off (:func:`surely_seen`): people seldom
  mark a keypoint seen nearly edge on (``bench_annotate.py --facing``), and each one skipped
  before the fit is a key press that brings the fit no nearer. They come spread over the car as
  far as they go (farthest-point order in the picture), so the first five pin the photo's scale,
  offset and view. Then the rest of what the view shows.
- **Once the car is fitted** it asks for the ghosts on the photo, the one the fit is least sure
  of first (its expected error in the photo, pixels): a mark there teaches the fit the most, and
  the ghosts it is sure of can be accepted with one key. A ghost off the photo is not asked.

Tried with the benchmark's simulated user (``benchmarks/bench_annotate.py``) and left out:
asking first the ghost whose mark would shrink the fit's posterior variance the most (the
Gaussian update of one click) asked the example's upper body first, where its ghosts were
accepted, and reached the hand-marked fit only near the end; on the real photos it needed no
fewer actions. Weighing the ghosts by how squarely they face the camera saved no key press
either: the keypoints the real photos' annotators left out mostly face the camera well (a mirror
in front, a rounded corner). Asking the near side's keypoints before the far side's made no
difference to the real photos and took the example from 8 to 23 actions.
"""
from __future__ import annotations

import functools

import numpy as np

from carbody.camera import View, project


#: A keypoint is marked surely once its region faces the camera this squarely (the cosine of
#: :func:`facing_cosines`); edge on (:data:`carbody.fit.visibility.FACING_COS`) nobody marks it.
#: On the 27 real photos the annotators marked 5 % of the keypoints the fitted view shows at
#: 0.1–0.2, 25 % at 0.2–0.3, 47 % at 0.3–0.4 and 56–69 % above (``bench_annotate.py --facing``).
FACING_SURE = 0.4

#: How far the view guessed before a fit may be off (degrees): the first keypoints asked face
#: the camera squarely over this much either side.
GUESS_SPREAD_DEG = 20.0


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


def facing_cosines(view: View, control_points: np.ndarray | None = None) -> dict[str, float]:
    """{name: cosine} for every markable name (both halves): how squarely the region at it that
    faces the camera most is seen (its outward normal against the way from the point to the
    camera: 1 face on, :data:`carbody.fit.visibility.FACING_COS` edge on).

    Args:
        view: the camera; a pinhole view's distance and aim in the unit of ``control_points``.
        control_points: (280, 3) the car (default the reference car, normalised units).
    """
    from carbody.camera import camera_direction
    from carbody.fit import keypoint_slots
    from carbody.fit.visibility import FacingTable

    cp = reference_car() if control_points is None else np.asarray(control_points, dtype=float)
    table = _reference_facing() if control_points is None else FacingTable(cp)
    slots = keypoint_slots()
    points = np.array([cp[slots[n].point_index] * slots[n].sign for n in table.names])
    d = camera_direction(view)
    if view.distance is None:
        toward = np.broadcast_to(d, points.shape)
    else:
        toward = np.asarray(view.aim, dtype=float) + view.distance * d - points
        toward = toward / np.linalg.norm(toward, axis=1, keepdims=True)
    cos = np.einsum("nj,rj->nr", toward, table.normals)
    best = np.max(np.where(table.owner, cos, -1.0), axis=1)
    return {n: float(c) for n, c in zip(table.names, best)}


@functools.cache
def _reference_facing():
    from carbody.fit.visibility import FacingTable

    return FacingTable(reference_car())


def markable(cosine: float) -> float:
    """How likely a person can mark a keypoint the view shows, from how squarely it is seen
    (:func:`facing_cosines`): 0 edge on, rising to 1 at :data:`FACING_SURE`."""
    from carbody.fit.visibility import FACING_COS

    return float(np.clip((cosine - FACING_COS) / (FACING_SURE - FACING_COS), 0.0, 1.0))


@functools.lru_cache(maxsize=64)  # (before a fit the view is one of a few guesses)
def shown_names(view: View) -> list[str]:
    """The names the reference car shows from ``view`` (both halves, id order)."""
    from carbody.fit import visible_keypoints

    return visible_keypoints(view, reference_car())


def ask_order(view: View, marks: dict, hidden: set[str], ghosts: dict[str, dict] | None = None) -> list[str]:
    """The keypoints to ask for, first first: unmarked, not hidden, and (after a fit) on the photo.

    After a fit, the ghosts on the photo, the one the fit is least sure of first (its expected
    error in the photo). Before one, the keypoints the guessed view shows squarely even if the
    guess is :data:`GUESS_SPREAD_DEG` off (:func:`surely_seen`), spread over the car
    (:func:`spread_order`); then the rest the view shows.

    Args:
        view: the fitted view, or the guessed one before a fit.
        marks: {name: (u, v)} placed so far.
        hidden: names the user said the photo does not show.
        ghosts: the fit's ghosts ({name: {"uv", "sd_px", "in_photo"}},
            :func:`~carbody.annotate.live_fit.fit_payload`), or None before a fit.
    """
    if ghosts:
        left = [n for n, g in ghosts.items() if n not in marks and n not in hidden and g.get("in_photo", True)]
        return sorted(left, key=lambda n: -ghosts[n]["sd_px"])
    left = [n for n in shown_names(view) if n not in marks and n not in hidden]
    sure = set(surely_seen(view))
    first = spread_order(view, [n for n in left if n in sure], dict(marks))
    return first + spread_order(view, [n for n in left if n not in sure], {**dict(marks), **{n: None for n in first}})


@functools.lru_cache(maxsize=64)
def surely_seen(view: View) -> list[str]:
    """The names the reference car shows squarely (:func:`markable` 1) from ``view`` and from
    views :data:`GUESS_SPREAD_DEG` either side of it: what to ask before a fit, when the view is
    a guess."""
    shown = set(shown_names(view))
    worst = None
    for delta in (-GUESS_SPREAD_DEG, 0.0, GUESS_SPREAD_DEG):
        cos = facing_cosines(View(view.azimuth + delta, view.elevation))
        worst = cos if worst is None else {n: min(c, worst[n]) for n, c in cos.items()}
    return [n for n in shown if markable(worst[n]) >= 1.0]
