"""Angle classes of the view classifier.

The paper's 13 classes (0°–180° by 15°) are the left side; the right side is their mirror image
(θ ↔ 360° − θ, picture flipped left–right). We label both sides with one azimuth class each:
24 classes k·15°, k = 0..23 (θ = 0 front, 90 left side, 180 rear, 270 right side, SPEC frame).
Classes 0° and 180° are their own mirror; the other 11 paper classes each gain a right-side twin.
A prediction therefore tells the side as well as the angle, which the fit needs.
"""
from __future__ import annotations

import numpy as np

#: Spacing of the classes, degrees.
CLASS_STEP_DEG = 15.0

#: Number of classes over the full circle.
N_CLASSES = 24

#: (24,) class angles θ_k in degrees.
CLASS_ANGLES_DEG = np.arange(N_CLASSES) * CLASS_STEP_DEG

def class_of(theta_deg: float) -> int:
    """Index of the class nearest to θ (degrees, any real)."""
    return int(np.round((theta_deg % 360.0) / CLASS_STEP_DEG)) % N_CLASSES


def mirror_class(k: int) -> int:
    """Class of the mirror image (picture flipped left–right): θ -> 360° − θ."""
    return (-int(k)) % N_CLASSES


#: (24,) class index after a left–right flip.
MIRROR_PERMUTATION = np.array([mirror_class(k) for k in range(N_CLASSES)])


def angular_difference(a_deg, b_deg):
    """|a − b| wrapped to [0, 180] degrees (elementwise)."""
    d = np.abs((np.asarray(a_deg, dtype=float) - np.asarray(b_deg, dtype=float)) % 360.0)
    return np.minimum(d, 360.0 - d)


def continuous_estimate(probabilities: np.ndarray) -> float:
    """A continuous θ (degrees, [0, 360)) from class probabilities (24,).

    The circular mean of the top class and its two neighbours, weighted by their probabilities,
    so it stays within half a class step of the top class's two-sided neighbourhood and ignores
    far-away mass (e.g. the front/rear ambiguity).
    """
    p = np.asarray(probabilities, dtype=float).reshape(-1)
    k = int(np.argmax(p))
    idx = [(k - 1) % N_CLASSES, k, (k + 1) % N_CLASSES]
    ang = np.radians(CLASS_ANGLES_DEG[idx])
    wts = p[idx]
    theta = np.degrees(np.arctan2((wts * np.sin(ang)).sum(), (wts * np.cos(ang)).sum()))
    return float(theta % 360.0)
