"""The camera contract of SPEC "Frames and units", in plain numpy.

The view angle θ is the camera azimuth around z, φ its elevation; the unit vector from the car
toward the camera is d = (sin θ·cos φ, −cos θ·cos φ, sin φ): θ = 0° front, 90° left side,
180° rear, 270° right side. The camera looks along f = −d; image-right is
r = (f × ẑ)/|f × ẑ| and image-up w = r × f. Roll ρ turns the camera about f: the up vector
becomes w·cos ρ + r·sin ρ, so a positive roll turns the picture's content counter-clockwise.
An orthographic camera puts a point p at u = u0 + s·(p·r), v = v0 − s·(p·w) (pixels, u right,
v down).
"""
from __future__ import annotations

import numpy as np


def camera_basis(view_deg: float, elevation_deg: float = 0.0,
                 roll_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors (d, r, w) of a view.

    Args:
        view_deg: azimuth θ, degrees (0 front, 90 left side, 180 rear, 270 right side).
        elevation_deg: elevation φ, degrees, |φ| < 90.
        roll_deg: roll ρ about the viewing direction, degrees.

    Returns:
        d: (3,) toward the camera; r: (3,) image-right; w: (3,) image-up (after roll).
    """
    t, p, q = np.radians([view_deg, elevation_deg, roll_deg])
    d = np.array([np.sin(t) * np.cos(p), -np.cos(t) * np.cos(p), np.sin(p)])
    f = -d
    r = np.cross(f, [0.0, 0.0, 1.0])
    r /= np.linalg.norm(r)
    w = np.cross(r, f)
    if q:
        r, w = r * np.cos(q) - w * np.sin(q), w * np.cos(q) + r * np.sin(q)
    return d, r, w


def project_orthographic(points: np.ndarray, view_deg: float, elevation_deg: float = 0.0,
                         roll_deg: float = 0.0, scale: float = 1.0,
                         origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """Pixel positions (N, 2) = (u, v) of (N, 3) points under the orthographic contract.

    ``scale`` is s in pixels per model unit, ``origin`` is (u0, v0) in pixels.
    """
    _, r, w = camera_basis(view_deg, elevation_deg, roll_deg)
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    return np.stack([origin[0] + scale * pts @ r, origin[1] - scale * pts @ w], axis=1)


def parse_view(view: str | float) -> float:
    """View angle θ in degrees from a number or a name such as ``"front 30°"``, ``"side"``,
    ``"rear 30"``, ``"right side"``, ``"left 90"``.

    Named views are on the left side (θ in [0, 180]) unless the name says ``right``:
    ``front N`` is θ = N, ``rear N`` is θ = 180 − N, ``side`` is 90; ``right`` mirrors to
    360 − θ.
    """
    from carbody.errors import RenderError

    if isinstance(view, (int, float, np.integer, np.floating)):
        return float(view) % 360.0
    text = str(view).strip().lower().replace("°", " ").replace("deg", " ")
    words = text.split()
    right = "right" in words
    words = [x for x in words if x not in ("right", "left", "view")]
    try:
        if len(words) == 1 and words[0] not in ("front", "rear", "side", "back"):
            return float(words[0]) % 360.0
        base = {"front": 0.0, "side": 90.0, "rear": 180.0, "back": 180.0}[words[0]]
        offset = float(words[1]) if len(words) > 1 else 0.0
        if len(words) > 2:
            raise ValueError
    except (KeyError, ValueError, IndexError):
        raise RenderError(f"cannot read view {view!r} (try 'front 30°', 'side', 'rear 30°' "
                          f"or an angle in degrees)") from None
    theta = base + offset if base < 180.0 else base - offset
    if base == 90.0 and offset:
        theta = 90.0 + offset
    return (360.0 - theta) % 360.0 if right else theta % 360.0
