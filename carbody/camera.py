"""The camera contract every stage uses (fit, render, view) (SPEC "Frames and units"), and the paper's eq. 1.

A view is an azimuth θ around z (0° front, 90° left side, 180° rear, 270° right side), an
elevation φ above the horizon and a roll ψ of the image about the viewing axis. The unit vector
from the car toward the camera is d = (sin θ cos φ, −cos θ cos φ, sin φ); forward f = −d,
image-right r = (f × ẑ)/|f × ẑ|, image-up w = r × f, both turned by the roll. A point p (car frame)
lands at u = u0 + s·(p·r), v = v0 − s·(p·w): orthographic, pixels, v down. A view may also
carry a camera distance D from an aim point a (a pinhole camera, a real photo's perspective): the
offset from the aim's image is then scaled by k = D / (D − (p − a)·d), nearer points larger, and
D → ∞ is the orthographic camera.

The paper writes the same camera as a rotation R = Rz(γ)·Ry(β)·Rx(α) (eq. 1) followed by dropping
x; :func:`view_rotation` gives that R with rows (d, r, w) and :func:`eq1_angles` its (α, β, γ).
"""
from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from carbody.errors import AngleError

#: Elevations this close to ±90° (straight down/up) have no image-right direction.
MAX_ABS_ELEVATION_DEG = 85.0

#: A photo rolled further than this is on its side or upside down: the fit moves the roll it is
#: told by at most ``FitPolicy.roll_range_deg``, so such a start is refused, not fitted.
MAX_ABS_ROLL_DEG = 90.0


@dataclass(frozen=True)
class View:
    """A camera direction, degrees.

    Attributes:
        azimuth: θ, 0° front, 90° left side, 180° rear, 270° right side.
        elevation: φ, camera height angle above the horizon (+ looking down at the car).
        roll: ψ about the viewing axis; + turns the picture's content counter-clockwise
            (image-up becomes w·cos ψ + r·sin ψ).
        distance: None for the orthographic camera of the contract; else a pinhole camera this
            far from ``aim`` along d, in the unit of the projected points.
        aim: (3,) the point the pinhole camera looks at, same unit.
    """

    azimuth: float
    elevation: float = 0.0
    roll: float = 0.0
    distance: float | None = None
    aim: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("azimuth", "elevation", "roll", "distance"):
            value = getattr(self, name)
            if name == "distance" and value is None:
                continue
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real) or not np.isfinite(value):
                raise AngleError(f"view {name} {value!r} is not a finite number")
        if abs(self.elevation) > MAX_ABS_ELEVATION_DEG:
            raise AngleError(f"view elevation {self.elevation:g}° is outside ±{MAX_ABS_ELEVATION_DEG:g}°")
        if self.distance is not None and not self.distance > 0:
            raise AngleError(f"camera distance {self.distance!r} is not a positive number")

    def scaled(self, factor: float) -> "View":
        """The same camera for the car scaled by ``factor`` about the origin (a pinhole view's
        distance and aim scale with it; the image does not change)."""
        if self.distance is None:
            return self
        return View(self.azimuth, self.elevation, self.roll, self.distance * factor,
                    tuple(float(a) * factor for a in self.aim))

    def as_dict(self) -> dict[str, float]:
        return {"azimuth_deg": float(self.azimuth), "elevation_deg": float(self.elevation),
                "roll_deg": float(self.roll)}


def check_azimuth(azimuth: float) -> float:
    """The azimuth if it lies in 0–360°, else :class:`AngleError`."""
    try:
        value = float(azimuth)
    except (TypeError, ValueError):
        raise AngleError(f"view angle {azimuth!r} is not a number") from None
    if not np.isfinite(value) or not 0.0 <= value <= 360.0:
        raise AngleError(f"view angle {azimuth!r} is outside 0–360°")
    return value


def camera_direction(view: View) -> np.ndarray:
    """(3,) unit vector from the car toward the camera, d."""
    t, p = np.radians(view.azimuth), np.radians(view.elevation)
    return np.array([np.sin(t) * np.cos(p), -np.cos(t) * np.cos(p), np.sin(p)])


def view_rotation(view: View) -> np.ndarray:
    """(3, 3) rotation with rows (d, r, w): toward the camera, image-right, image-up.

    ``view_rotation(v) @ p`` = (depth toward the camera, image-right, image-up) of a point p, the
    paper's rotate-then-drop-x (eq. 1).
    """
    d = camera_direction(view)
    f = -d
    r = np.array([f[1], -f[0], 0.0])  # f × ẑ (written out: np.cross costs more than the fit's solve step)
    r /= np.sqrt(r @ r)
    w = np.array([r[1] * f[2], -r[0] * f[2], r[0] * f[1] - r[1] * f[0]])  # r × f, r_z = 0
    c, s = np.cos(np.radians(view.roll)), np.sin(np.radians(view.roll))
    return np.array([d, c * r - s * w, c * w + s * r])


def eq1_rotation(alpha: float, beta: float, gamma: float) -> np.ndarray:
    """The paper's eq. 1, R = Rz(γ)·Ry(β)·Rx(α); angles in degrees, (3, 3)."""
    a, b, g = np.radians([alpha, beta, gamma])
    rz = np.array([[np.cos(g), -np.sin(g), 0], [np.sin(g), np.cos(g), 0], [0, 0, 1]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    return rz @ ry @ rx


def eq1_angles(view: View) -> tuple[float, float, float]:
    """(α, β, γ) degrees with ``eq1_rotation(α, β, γ) == view_rotation(view)``."""
    r = view_rotation(view)
    beta = -np.arcsin(np.clip(r[2, 0], -1.0, 1.0))
    alpha = np.arctan2(r[2, 1], r[2, 2])
    gamma = np.arctan2(r[1, 0], r[0, 0])
    return tuple(float(v) for v in np.degrees([alpha, beta, gamma]))


def project(points: np.ndarray, view: View, scale: float = 1.0,
            offset: tuple[float, float] | np.ndarray = (0.0, 0.0), max_factor: float | None = None) -> np.ndarray:
    """Image coordinates of car-frame points.

    Args:
        points: (..., 3) float, car frame (any length unit).
        view: the camera.
        scale: pixels per length unit, s.
        offset: (u0, v0) pixels, image position of the car-frame origin.
        max_factor: a pinhole's perspective factor clamped to this (:func:`perspective_factors`)
            instead of refusing a point at or behind the camera.
    Returns:
        (..., 2) float, pixels (u right, v down).
    """
    rot = view_rotation(view)
    p = np.asarray(points, dtype=float)
    if view.distance is not None:
        aim = np.asarray(view.aim, dtype=float)
        p = aim + (p - aim) * perspective_factors(p, view, max_factor)[..., None]
    u = offset[0] + scale * (p @ rot[1])
    v = offset[1] - scale * (p @ rot[2])
    return np.stack([u, v], axis=-1)


def perspective_factors(points: np.ndarray, view: View, max_factor: float | None = None) -> np.ndarray:
    """(...,) float, k = D / (D − (p − aim)·d): how much larger the pinhole camera shows each
    point than the orthographic one (1 everywhere for an orthographic view).

    Args:
        max_factor: clamp k to this instead of refusing points near or behind the camera (a
            fit's intermediate shapes may stray there).
    Raises:
        AngleError: a point at or behind the camera (without ``max_factor``).
    """
    p = np.asarray(points, dtype=float)
    if view.distance is None:
        return np.ones(p.shape[:-1])
    gap = view.distance - (p - np.asarray(view.aim, dtype=float)) @ camera_direction(view)
    if max_factor is not None:
        return view.distance / np.maximum(gap, view.distance / max_factor)
    if np.any(gap <= 1e-6 * view.distance):
        raise AngleError(f"camera distance {view.distance:g} puts the camera inside the car")
    return view.distance / gap


def look_at_homography(target_px: np.ndarray, principal_px: np.ndarray, focal_px: float) -> np.ndarray:
    """(3, 3) homography from a photo's pixels to those of the same camera turned (about its
    centre, by the least rotation) to look straight at ``target_px``.

    A photo's optical axis goes through its principal point (``principal_px``, the image centre
    of an uncropped photo); a car off that axis is seen obliquely by the image plane, which the
    pinhole model aimed at the car (:class:`View` with a distance) does not describe. The turned
    camera's picture does; it has the same focal length and principal point.

    Args:
        target_px: (2,) pixels (u right, v down) the turned camera looks at.
        principal_px: (2,) pixels, the optical axis.
        focal_px: focal length, pixels.
    """
    K = np.array([[focal_px, 0.0, principal_px[0]], [0.0, focal_px, principal_px[1]], [0.0, 0.0, 1.0]])
    ray = np.linalg.solve(K, [target_px[0], target_px[1], 1.0])
    ray /= np.linalg.norm(ray)
    axis = np.cross(ray, [0.0, 0.0, 1.0])
    s, c = np.linalg.norm(axis), ray[2]
    if s < 1e-12:
        return np.eye(3)
    k = axis / s
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    R = np.eye(3) + s * kx + (1.0 - c) * kx @ kx  # Rodrigues: takes ray onto the axis
    return K @ R @ np.linalg.inv(K)


def apply_homography(H: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(..., 2) pixels mapped by a (3, 3) homography."""
    p = np.asarray(uv, dtype=float)
    q = p @ H[:, :2].T + H[:, 2]
    return q[..., :2] / q[..., 2:3]


def depth(points: np.ndarray, view: View) -> np.ndarray:
    """(...,) distance of each point toward the camera (larger = nearer), same unit as points."""
    return np.asarray(points, dtype=float) @ camera_direction(view)


def mirror_view(view: View) -> View:
    """The view of the other side: θ ↔ 360° − θ (the image flips left–right, roll changes sign)."""
    return View((360.0 - view.azimuth) % 360.0, view.elevation, -view.roll, view.distance,
                (-view.aim[0], view.aim[1], view.aim[2]))


def degrees_from_axis(azimuth: float) -> float:
    """How far (degrees) a view's azimuth lies from the car's long axis: 0 straight from the
    front or rear, 90 from a side."""
    return min(abs((azimuth + 180.0) % 360.0 - 180.0), abs(azimuth % 360.0 - 180.0))


def read_view(text: str | float) -> float:
    """A view as a person types it: an azimuth in degrees (0–360) or a name (:func:`parse_view`:
    ``"front 30"``, ``"rear 30"``, ``"side"``, ``"front 30 right"``, its angle 0–180°).

    Raises:
        AngleError: not a number or a name, or an angle out of its range (``"front 999"``).
    """
    if isinstance(text, (bool, np.bool_)) or not isinstance(text, (str, numbers.Real)):
        raise AngleError(f"view {text!r} is neither an angle in degrees nor a name such as 'front 30'")
    try:
        value = float(text)
    except ValueError:
        words = _view_words(text)
        if len(words) == 1 and words[0] not in _VIEW_BASES:  # "45°": a number with its unit
            return check_azimuth(_view_number(words[0], text))
        if len(words) == 2:
            offset = _view_number(words[1], text)
            if not 0.0 <= offset <= 180.0:
                raise AngleError(f"view {text!r}: the angle after {words[0]!r} lies outside 0–180°") from None
        return parse_view(text)
    return check_azimuth(value)


#: The azimuth each view name starts from, degrees.
_VIEW_BASES = {"front": 0.0, "side": 90.0, "rear": 180.0, "back": 180.0}


def _view_words(view: str) -> list[str]:
    """The words of a view's name that say the angle ("right", "left", "view" and units dropped)."""
    text = str(view).strip().lower().replace("°", " ").replace("deg", " ")
    return [x for x in text.split() if x not in ("right", "left", "view")]


def _view_number(word: str, view) -> float:
    try:
        value = float(word)
    except ValueError:
        raise AngleError(f"cannot read view {view!r} (try 'front 30°', 'side', 'rear 30°' "
                         f"or an angle in degrees)") from None
    if not np.isfinite(value):
        raise AngleError(f"view {view!r} is not a finite angle")
    return value


def parse_view(view: str | float) -> float:
    """View angle θ in degrees from a number or a name such as ``"front 30°"``, ``"side"``,
    ``"rear 30"``, ``"right side"``, ``"left 90"``.

    Named views are on the left side (θ in [0, 180]) unless the name says ``right``:
    ``front N`` is θ = N, ``rear N`` is θ = 180 − N, ``side`` is 90; ``right`` mirrors to
    360 − θ.
    """
    if isinstance(view, (int, float, np.integer, np.floating)):
        return float(view) % 360.0
    right = "right" in str(view).lower().split()
    words = _view_words(view)
    try:
        if len(words) == 1 and words[0] not in _VIEW_BASES:
            return float(words[0]) % 360.0
        base = _VIEW_BASES[words[0]]
        offset = float(words[1]) if len(words) > 1 else 0.0
        if len(words) > 2:
            raise ValueError
    except (KeyError, ValueError, IndexError):
        raise AngleError(f"cannot read view {view!r} (try 'front 30°', 'side', 'rear 30°' "
                          f"or an angle in degrees)") from None
    theta = base + offset if base < 180.0 else base - offset
    if base == 90.0 and offset:
        theta = 90.0 + offset
    return (360.0 - theta) % 360.0 if right else theta % 360.0
