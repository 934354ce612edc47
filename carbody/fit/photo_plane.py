"""The photo as an image plane in the car's frame (mm), for a CAD viewer beside the car.

Lined up with a fit (:func:`fitted_plane`), the plane stands behind the car square to the fitted
camera, so that looking along that camera the wireframe lies on the photo, as on the overlay;
before a fit (:func:`side_plane`), the photo stands upright in the car's side plane. A viewer
(FreeCAD's image plane) shows a picture as stored, while carbody reads a phone photo stored on
its side upright (EXIF orientation 5–8) and its marks are on the upright picture: the plane's
axes are the stored picture's, turned so it shows upright (seen from behind, for the mirrored
orientations).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from carbody.errors import ImageError

#: EXIF orientation → the stored picture's right and up, in the upright picture's (right, up):
#: 6, for one, is stored turned a quarter anticlockwise, so its right points down.
STORED_AXES = {1: ((1, 0), (0, 1)), 2: ((-1, 0), (0, 1)), 3: ((-1, 0), (0, -1)), 4: ((1, 0), (0, -1)),
               5: ((0, -1), (-1, 0)), 6: ((0, -1), (1, 0)), 7: ((0, 1), (1, 0)), 8: ((0, 1), (-1, 0))}

#: The fitted plane stands this fraction of the car's size behind its farthest point.
BEHIND_FRACTION = 0.05


@dataclass(frozen=True)
class PhotoPlane:
    """A picture placed in the car's frame.

    Attributes:
        centre_mm: (3,) the picture's centre, mm.
        x_axis, y_axis: (3,) unit: the stored picture's right and up (a viewer's image plane
            spans the stored width along ``x_axis``, the height along ``y_axis``).
        width_mm, height_mm: the stored picture's size, mm.
        right, up: (3,) unit: the upright picture's right and up; the camera looks along
            −(right × up).
        lineup_px: root-mean-square distance, pixels, between where the fitted camera and the
            plane put the car's control points (0 but for rounding); None before a fit.
        eye_mm: (3,) a pinhole camera's centre: the plane lines up seen from there (a
            perspective view); None: seen along the camera from any distance (orthographic).
    """

    centre_mm: np.ndarray
    x_axis: np.ndarray
    y_axis: np.ndarray
    width_mm: float
    height_mm: float
    right: np.ndarray
    up: np.ndarray
    lineup_px: float | None = None
    eye_mm: np.ndarray | None = None

    def as_dict(self) -> dict:
        out = {k: [float(v) for v in getattr(self, k)] for k in ("centre_mm", "x_axis", "y_axis", "right", "up")}
        out.update(width_mm=float(self.width_mm), height_mm=float(self.height_mm),
                   lineup_px=None if self.lineup_px is None else float(self.lineup_px),
                   eye_mm=None if self.eye_mm is None else [float(v) for v in self.eye_mm])
        return out

    def on_plane(self, points_mm: np.ndarray) -> np.ndarray:
        """(n, 3) mm: where points (n, 3) mm are seen on the plane, looking along the camera
        (from ``eye_mm``, or square to the plane)."""
        p = np.asarray(points_mm, float)
        normal = np.cross(self.right, self.up)
        if self.eye_mm is None:
            return p - ((p - self.centre_mm) @ normal)[:, None] * normal
        ray = p - self.eye_mm
        return self.eye_mm + ray * (((self.centre_mm - self.eye_mm) @ normal) / (ray @ normal))[:, None]

    def stored_pixel(self, points_mm: np.ndarray, stored_size: tuple[int, int]) -> np.ndarray:
        """(n, 2) pixels of the stored picture (as a viewer shows it on the plane) where points
        (n, 3) mm are seen."""
        local = self.on_plane(points_mm) - self.centre_mm
        w, h = stored_size
        return np.stack([(local @ self.x_axis / self.width_mm + 0.5) * w,
                         (0.5 - local @ self.y_axis / self.height_mm) * h], axis=-1)

    def photo_pixel(self, points_mm: np.ndarray, upright_size: tuple[int, int]) -> np.ndarray:
        """(n, 2) pixels of the upright picture (the fit's) where points (n, 3) mm are seen."""
        local = self.on_plane(points_mm) - self.centre_mm
        mm_per_px = (self.width_mm * abs(self.x_axis @ self.right) + self.height_mm * abs(self.y_axis @ self.right)) \
            / upright_size[0]
        return np.stack([upright_size[0] / 2 + local @ self.right / mm_per_px,
                         upright_size[1] / 2 - local @ self.up / mm_per_px], axis=-1)


def read_picture(image_path: str | Path) -> tuple[tuple[int, int], int]:
    """((width, height) pixels as stored, EXIF orientation 1–8) of an image file.

    Raises:
        ImageError: not an image file.
    """
    from carbody.inputs import input_file
    from carbody.view.predict import check_stored_size, exif_orientation, open_picture

    input_file(image_path, "image file", ImageError)
    check_stored_size(image_path)
    try:
        with open_picture(image_path) as im:
            size = im.size
    except (OSError, ValueError) as exc:
        raise ImageError(f"{image_path}: not an image ({exc})") from None
    return size, exif_orientation(image_path)


def upright_size(stored: tuple[int, int], orientation: int) -> tuple[int, int]:
    """(width, height) of a stored picture turned upright by its EXIF orientation."""
    return (stored[1], stored[0]) if orientation >= 5 else stored


def place_photo(picture: tuple[tuple[int, int], int], centre_mm: np.ndarray, right: np.ndarray, up: np.ndarray,
                mm_per_px: float, eye_mm: np.ndarray | None = None) -> PhotoPlane:
    """The photo's plane (``picture`` from :func:`read_picture`) from where its upright picture
    lies: centre (3,) mm, right and up (3,) unit vectors, ``mm_per_px`` its scale."""
    (w, h), orientation = picture
    (xr, xu), (yr, yu) = STORED_AXES[orientation]
    right, up = np.asarray(right, float), np.asarray(up, float)
    return PhotoPlane(np.asarray(centre_mm, float), xr * right + xu * up, yr * right + yu * up,
                      w * mm_per_px, h * mm_per_px, right, up, eye_mm=eye_mm)


def side_plane(image_path: str | Path, width_mm: float = 5000.0) -> PhotoPlane:
    """The upright photo in the car's side plane (x = 0), seen from the car's left (the nose to
    the left, as a left side view shows it), ``width_mm`` wide, centred on the front wheel."""
    picture = read_picture(image_path)
    return place_photo(picture, np.zeros(3), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]),
                       width_mm / upright_size(*picture)[0])


def fitted_plane(result, image_path: str | Path) -> PhotoPlane:
    """The photo lined up with a fit (a :class:`~carbody.fit.result.FitResult` of it),
    behind the car: looking along the fitted camera, each of the car's control points falls
    where the fit reprojects it on the photo.

    An orthographic camera: the plane stands square to the view, seen from any distance along
    it. A pinhole camera: the plane is the photo's own image plane (square to its optical axis,
    which a camera turned toward an off-centre car is not) pushed back behind the car, lined up
    as seen from the camera's eye (``eye_mm``): every photo corner lies on its pixel's ray.
    """
    from carbody.camera import apply_homography, view_rotation

    half = result.wireframe.control_points
    car = np.concatenate([half, half * [-1.0, 1.0, 1.0]])  # both halves, mm
    size = float(np.ptp(car, axis=0).max())
    picture = read_picture(image_path)
    width, height = upright_size(*picture)
    view = result.view.scaled(result.mm_per_unit)
    d, r, w = view_rotation(view)
    scale, (u0, v0) = result.solution.scale / result.mm_per_unit, result.solution.offset  # px per mm

    def at_aim_depth(uv: np.ndarray) -> np.ndarray:
        """(n, 3) mm: the points square to the view through the aim (the origin, orthographic)
        that the fitted camera shows at photo pixels ``uv`` (n, 2)."""
        if result.to_photo is not None:
            uv = apply_homography(np.linalg.inv(result.to_photo), uv)
        a, b = (uv[:, 0] - u0) / scale, -(uv[:, 1] - v0) / scale
        return a[:, None] * r + b[:, None] * w + (np.asarray(view.aim) @ d) * d

    corners = np.array([[0.0, 0.0], [width, 0.0], [width, height], [0.0, height]])  # top-left, clockwise
    if view.distance is None:
        behind = (car @ d).min() - BEHIND_FRACTION * size
        x = at_aim_depth(corners) + behind * d
        eye = None
    else:
        eye = np.asarray(view.aim) + view.distance * d
        rays = at_aim_depth(corners) - eye
        # the photo's corners on one plane square to its optical axis: a rectangle, so its
        # diagonals bisect each other (λ1·ρ1 + λ3·ρ3 = λ2·ρ2 + λ4·ρ4)
        lam = np.linalg.svd(np.stack([rays[0], -rays[1], rays[2], -rays[3]], axis=1))[2][-1]
        x = (lam * np.sign(lam.sum()))[:, None] * rays  # in front of the eye
        axis = np.cross(x[1] - x[0], x[3] - x[0])
        axis *= np.sign(axis @ x[0]) / np.linalg.norm(axis)  # away from the eye
        x = eye + x * ((((car - eye) @ axis).max() + BEHIND_FRACTION * size) / (x[0] @ axis))
    right, up = x[1] - x[0], x[0] - x[3]
    plane = place_photo(picture, x.mean(axis=0), right / np.linalg.norm(right), up / np.linalg.norm(up),
                        np.linalg.norm(right) / width, eye_mm=eye)
    seen = plane.photo_pixel(car, (width, height))
    return replace(plane, lineup_px=float(np.sqrt(np.mean(np.sum((seen - result.project_points(car)) ** 2, axis=1)))))
