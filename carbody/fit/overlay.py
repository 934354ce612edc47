"""The overlay picture (paper Fig. 9–10): photo, annotated (red) and reprojected (green)
keypoints, and the fitted wireframe projected with the refined camera; marks the fit cannot
follow (the diagnostics' ``suspect``) ringed in magenta, and marks left out (the diagnostics'
``rejected``) crossed out in magenta, joined to where the fitted car puts them; the wheels'
hubs found in the photo (:mod:`carbody.fit.wheels`) ringed in red, the fitted hubs in green."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from carbody.errors import ImageError


def draw_overlay(image: np.ndarray, result, labels: bool = True) -> np.ndarray:
    """The overlay as a new (h, w, 3) uint8 BGR image.

    Args:
        image: (h, w, 3) uint8 BGR photo.
        result: a :class:`carbody.fit.result.FitResult`.
        labels: write each keypoint's number next to it.
    """
    import cv2

    from carbody.fit.keypoints_io import keypoint_slots
    from carbody.wireframe import MIRROR, sample_curves

    out = image.copy()
    thick = max(1, round(max(out.shape[:2]) / 800))

    def label(slot, at: tuple[int, int], colour: tuple[int, int, int]) -> None:  # Fig. 6 number, ' for a mirror
        cv2.putText(out, str(slot.keypoint_id) + ("'" if slot.is_mirror else ""), at,
                    cv2.FONT_HERSHEY_SIMPLEX, 0.35 * thick, colour, thick, cv2.LINE_AA)
    cp = result.wireframe.control_points
    for half in (cp, cp * MIRROR):
        for curve in sample_curves(half, 24):
            pts = result.project_points(curve)
            cv2.polylines(out, [np.round(pts * 16).astype(np.int32)], False, (255, 160, 0),
                          thick, cv2.LINE_AA, shift=4)
    reproj = result.reprojected()
    r = 2 + 2 * thick
    suspects = set(result.diagnostics.suspect)
    for slot, (u, v), (pu, pv) in zip(result.slots, result.uv, reproj):
        if slot.name in suspects:
            cv2.circle(out, (round(u), round(v)), 3 * r, (255, 0, 255), 2 * thick, cv2.LINE_AA)
        cv2.line(out, (round(u), round(v)), (round(pu), round(pv)), (0, 200, 255), thick, cv2.LINE_AA)
        cv2.circle(out, (round(u), round(v)), r, (0, 0, 255), -1, cv2.LINE_AA)
        cv2.circle(out, (round(pu), round(pv)), r, (0, 200, 0), thick, cv2.LINE_AA)
        if labels:
            label(slot, (round(u) + r + 1, round(v) - r - 1), (0, 0, 200))
    slots = keypoint_slots()
    for name, mark in result.diagnostics.rejected.items():
        (u, v), slot = mark.uv, slots[name]
        pu, pv = result.project_points(cp[slot.point_index] * slot.sign)
        cv2.line(out, (round(u), round(v)), (round(pu), round(pv)), (255, 0, 255), thick, cv2.LINE_AA)
        cv2.circle(out, (round(pu), round(pv)), r, (0, 200, 0), thick, cv2.LINE_AA)
        for du in (-1, 1):
            cv2.line(out, (round(u - 2 * r), round(v - 2 * r * du)), (round(u + 2 * r), round(v + 2 * r * du)),
                     (255, 0, 255), 2 * thick, cv2.LINE_AA)
        if labels:
            label(slot, (round(u) + 2 * r + 1, round(v) - 2 * r - 1), (255, 0, 255))
    if result.wheels is not None and result.wheels.used:  # hubs found in the photo: red rings, fitted green
        from carbody.fit.wheels import WHEELS, hub_points

        fitted = result.project_points(hub_points(cp))
        for hub in result.wheels.wheels:
            (u, v), (pu, pv) = hub["found_px"], fitted[WHEELS.index(hub["wheel"])]
            cv2.line(out, (round(u), round(v)), (round(pu), round(pv)), (0, 200, 255), thick, cv2.LINE_AA)
            cv2.circle(out, (round(u), round(v)), 2 * r, (0, 0, 255), thick, cv2.LINE_AA)
            cv2.circle(out, (round(pu), round(pv)), r, (0, 200, 0), thick, cv2.LINE_AA)
    return out


def write_image(path: str | Path, image: np.ndarray) -> Path:
    """Write an image atomically, in the format its ending names (PNG, JPEG): encoded in memory
    and written by Python, so that a full disk says so.

    Raises:
        ImageError: OpenCV cannot encode the picture in that format.
        OSError: the file cannot be written.
    """
    import cv2

    from carbody.occ.step_curves import atomic_write

    path = Path(path)
    ok, data = cv2.imencode(path.suffix or ".png", image)
    if not ok:
        raise ImageError(f"{path}: cannot encode the picture as {path.suffix or '.png'}")
    return atomic_write(path, lambda tmp: Path(tmp).write_bytes(data.tobytes()))
