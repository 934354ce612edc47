"""Which views could have marked these keypoints: a likelihood over the 24 classes from names.

A person marks only what they see, so the names of the marks say which end and side of the car
faced the camera (``nose_centre`` is not seen from behind, a ``_right`` twin not from the left).
Per class θ_k the chance that a keypoint is visible comes from the wireframe's geometry
(:func:`carbody.fit.visibility.visible_keypoints` on the library's mean model, over a few
elevations and azimuths inside the class); the likelihood of a set of marks is the product over
them of ε + (1 − ε)·P(visible | θ_k), ε for a mark the model calls hidden (a marking slip, or a
car unlike the mean). Multiplied into the classifier's probabilities it removes most front/rear
and left/right mistakes, which pixels at 64 px tell badly. Nothing here is fitted on photos.
"""
from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np

from carbody.view.labels import CLASS_ANGLES_DEG, N_CLASSES

#: Chance that a mark the visibility model calls hidden is marked anyway.
HIDDEN_MARK_CHANCE = 0.05

#: Elevations (deg) and azimuth offsets inside a class (deg) the visibility is averaged over.
ELEVATIONS_DEG = (3.0, 12.0, 25.0)
OFFSETS_DEG = (-5.0, 0.0, 5.0)


#: The table as computed by :func:`compute_visibility_table` (15 s), shipped so a call is instant.
TABLE_FILE = Path(__file__).resolve().parent / "weights" / "mark_visibility.json"


def compute_visibility_table(classes=range(N_CLASSES)) -> tuple[tuple[str, ...], np.ndarray]:
    """(keypoint names, (len(classes), n) P(visible | class)) from the geometry."""
    from carbody.camera import View
    from carbody.fit.keypoints_io import keypoint_slots
    from carbody.fit.visibility import visible_keypoints

    names = tuple(keypoint_slots().keys())
    index = {n: i for i, n in enumerate(names)}
    classes = list(classes)
    table = np.zeros((len(classes), len(names)))
    shots = len(ELEVATIONS_DEG) * len(OFFSETS_DEG)
    for row, k in enumerate(classes):
        for el in ELEVATIONS_DEG:
            for off in OFFSETS_DEG:
                for n in visible_keypoints(View((CLASS_ANGLES_DEG[k] + off) % 360.0, el)):
                    table[row, index[n]] += 1.0 / shots
    return names, table


def write_visibility_table(path: Path = TABLE_FILE) -> Path:
    """Compute the table and write it as JSON (after a change of topology or library)."""
    names, table = compute_visibility_table()
    path.write_text(json.dumps({"names": list(names), "classes_deg": CLASS_ANGLES_DEG.tolist(),
                                "elevations_deg": ELEVATIONS_DEG, "offsets_deg": OFFSETS_DEG,
                                "p_visible": np.round(table, 4).tolist()}))
    return path


@functools.lru_cache(maxsize=1)
def visibility_table() -> tuple[tuple[str, ...], np.ndarray]:
    """(keypoint names, (24, n) P(visible | class)): the shipped table, computed when absent."""
    if TABLE_FILE.is_file():
        data = json.loads(TABLE_FILE.read_text())
        return tuple(data["names"]), np.asarray(data["p_visible"], dtype=float)
    return compute_visibility_table()


def mark_likelihood(marked, hidden_chance: float = HIDDEN_MARK_CHANCE) -> np.ndarray:
    """(24,) likelihood (max 1) of the views given the marked keypoint names (unknown names are
    ignored; no known name gives all ones)."""
    names, table = visibility_table()
    index = {n: i for i, n in enumerate(names)}
    cols = [index[n] for n in marked if n in index]
    if not cols:
        return np.ones(N_CLASSES)
    log = np.log(hidden_chance + (1 - hidden_chance) * table[:, cols]).sum(1)
    return np.exp(log - log.max())


def combine_with_marks(probabilities: np.ndarray, marked) -> np.ndarray:
    """(24,) the classifier's probabilities times :func:`mark_likelihood`, normalised."""
    p = np.asarray(probabilities, dtype=float) * mark_likelihood(marked)
    return p / p.sum() if p.sum() > 0 else np.asarray(probabilities, dtype=float)
