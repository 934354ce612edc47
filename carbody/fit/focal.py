"""A photo's focal length in pixels: from a 35 mm-equivalent focal length, or the photo's EXIF.

A fit whose camera turns toward a car off the photo's centre uses it for the turn's angle
(:func:`carbody.fit.fit_wireframe`, ``focal_px``); without it the fit estimates the focal length
from the distance it finds, which such a car misleads.
"""
from __future__ import annotations

import math
import numbers
from pathlib import Path

#: Diagonal of the 35 mm film frame the equivalent focal length refers to, mm.
FILM_DIAGONAL_MM = 43.27


def focal_length_px(image: str | Path | None, size: tuple[int, int],
                    focal_35mm: float | None) -> tuple[float | None, str]:
    """The focal length in pixels from a 35 mm-equivalent one, else from the photo's EXIF
    (``FocalLengthIn35mmFilm``, used only when the EXIF image size is the photo's, turned upright:
    a cropped or resized photo's EXIF no longer fits it; ``image`` None: no file to read). Returns (pixels or
    None, where it came from)."""
    from carbody.errors import FitError
    from carbody.view.predict import exif_orientation, open_picture

    diagonal = math.hypot(*size)
    if focal_35mm is not None:
        if not (isinstance(focal_35mm, numbers.Real) and math.isfinite(focal_35mm) and 5.0 <= focal_35mm <= 2000.0):
            raise FitError(f"focal length {focal_35mm!r} mm (35 mm equivalent) is not a lens's (5–2000 mm)")
        return focal_35mm * diagonal / FILM_DIAGONAL_MM, "given"
    if image is None:
        return None, ""
    try:
        with open_picture(image) as im:
            exif = im.getexif().get_ifd(0x8769)
        f35, width, height = float(exif.get(0xA405) or 0), exif.get(0xA002), exif.get(0xA003)
    except Exception:  # no readable EXIF, or a focal length that is no number: the fit finds the distance from perspective
        return None, ""
    if exif_orientation(image) >= 5:  # stored on its side; ``size`` is the upright picture's
        width, height = height, width
    if not (math.isfinite(f35) and f35 > 0) or (width, height) != tuple(size):
        return None, ""
    return f35 * diagonal / FILM_DIAGONAL_MM, f"EXIF {f35:g} mm (35 mm equivalent)"
