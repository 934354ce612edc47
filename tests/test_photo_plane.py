"""The photo as an image plane in the car's frame: lined up with the fitted camera (orthographic,
pinhole, a pinhole turned toward an off-centre car), and upright whatever its EXIF orientation."""
from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from carbody.camera import View
from carbody.fit.photo_plane import fitted_plane, side_plane
from carbody.fit.single_view import fit_wireframe
from carbody.view.predict import upright
from tests.conftest import REPO, camera_jpeg, off_centre_photo, run_cli


def _both_halves(result):
    half = result.wireframe.control_points
    return np.concatenate([half, half * [-1.0, 1.0, 1.0]])


def _example():
    marks = json.loads((REPO / "examples" / "car_keypoints.json").read_text())["keypoints"]
    return REPO / "examples" / "car.png", {k: tuple(v) for k, v in marks.items()}


@pytest.mark.parametrize("camera", ["orthographic", "pinhole"])
def test_the_photo_stands_behind_the_car_where_the_fitted_camera_sees_it(library, camera):
    """Seen along the fitted camera (from its eye, for a pinhole), every control point of the car
    lies on the photo where the fit reprojects it, and the marks where they were clicked (within
    the fit's residual); the plane stands behind the car."""
    image, marks = _example()
    size = Image.open(image).size
    result = fit_wireframe(marks, View(30), library, image_size=size,
                           camera_distance_mm=None if camera == "orthographic" else "auto")
    assert (result.view.distance is None) == (camera == "orthographic")
    plane = fitted_plane(result, image)
    car = _both_halves(result)
    assert np.abs(plane.photo_pixel(car, size) - result.project_points(car)).max() < 1e-6
    assert plane.lineup_px < 1e-6
    named = result.keypoints_mm()
    clicked = np.array([marks[s.name] for s in result.slots])
    seen = plane.photo_pixel(np.array([named[s.name] for s in result.slots]), size)
    assert np.allclose(np.linalg.norm(seen - clicked, axis=1), list(result.residuals_px().values()), atol=1e-6)
    normal = np.cross(plane.right, plane.up)
    if plane.eye_mm is None:  # toward the camera: the car nearer than the plane
        assert ((car - plane.centre_mm) @ normal).min() > 0
    else:
        assert (plane.eye_mm - plane.centre_mm) @ normal > ((car - plane.centre_mm) @ normal).max() > 0
    # the stored picture is the upright one (no EXIF turn): its axes are the picture's
    assert np.allclose(plane.x_axis, plane.right) and np.allclose(plane.y_axis, plane.up)
    assert plane.width_mm / plane.height_mm == pytest.approx(size[0] / size[1])


def test_a_camera_turned_to_an_off_centre_car_gets_the_photo_s_own_image_plane(library, tmp_path):
    """A car off the photo's centre is fitted by a camera turned toward it (a homography back to
    the photo): the plane is still the photo's own, square to the ray through the photo's
    centre (its optical axis), and lines up from the eye."""
    truth = library.points(library.original("Volvo V60"))
    marks = off_centre_photo(truth, View(30, 10), noise=0.5)
    focal = camera_jpeg(tmp_path / "photo.jpg")
    result = fit_wireframe(marks, View(30, 10), library.without("Volvo V60"), image_size=(2000, 1000),
                           camera_distance_mm="auto", focal_px=focal)
    assert result.to_photo is not None and result.camera_turn_deg > 10
    plane = fitted_plane(result, tmp_path / "photo.jpg")
    car = _both_halves(result)
    # (the turn uses the focal length it was told, the fitted pinhole its own scale × distance:
    # the two cameras agree to about a tenth of a pixel, not exactly)
    assert np.abs(plane.photo_pixel(car, (2000, 1000)) - result.project_points(car)).max() < 0.25
    assert plane.lineup_px < 0.05
    axis = plane.centre_mm - plane.eye_mm
    assert np.degrees(np.arccos(abs(axis @ np.cross(plane.right, plane.up)) / np.linalg.norm(axis))) < 0.5
    assert abs(plane.right @ plane.up) < 1e-3


@pytest.mark.parametrize("orientation", range(1, 9))
def test_a_photo_stored_turned_is_shown_upright(tmp_path, orientation):
    """A viewer shows the picture as stored; carbody reads it turned upright by its EXIF
    orientation. Whatever the orientation, a point the plane shows at a stored pixel is the one
    the upright picture has there: the upright picture reads left to right along the car seen
    from its left (nose to the left), up along z."""
    stored_wh = (300, 200)
    exif = Image.Exif()
    exif[0x0112] = orientation
    path = tmp_path / "photo.jpg"
    Image.new("RGB", stored_wh).save(path, exif=exif)
    plane = side_plane(path, 4000.0)
    # which stored pixel each upright pixel is (carbody's own turn, read_image's)
    sx, sy = np.meshgrid(np.arange(stored_wh[0]), np.arange(stored_wh[1]))
    turned = upright(np.stack([sx, sy], axis=-1), orientation)
    up_h, up_w = turned.shape[:2]
    assert plane.width_mm * abs(plane.x_axis @ plane.right) + plane.height_mm * abs(plane.y_axis @ plane.right) \
        == pytest.approx(4000.0)
    rng = np.random.default_rng(orientation)
    points = np.column_stack([np.zeros(50), rng.uniform(-1900, 1900, 50), rng.uniform(-1000, 1000, 50)])
    u, v = plane.photo_pixel(points, (up_w, up_h)).T
    assert u.min() > 0 and u.max() < up_w and v.min() > 0 and v.max() < up_h
    looked_up = turned[v.astype(int), u.astype(int)] + 0.5
    assert np.abs(plane.stored_pixel(points, stored_wh) - looked_up).max() <= 0.5 + 1e-9
    # nose to the left, up is up: larger y (toward the rear) to the right, larger z higher
    assert np.allclose(plane.right, [0, 1, 0]) and np.allclose(plane.up, [0, 0, 1])


def test_photo_plane_command_prints_json_and_refuses_bad_input(tmp_path):
    proc = run_cli("photo-plane", str(REPO / "examples" / "car.png"), "--width", "4000", check=True)
    plane = json.loads(proc.stdout)
    w, h = Image.open(REPO / "examples" / "car.png").size
    assert plane["width_mm"] == 4000.0 and plane["height_mm"] == pytest.approx(4000.0 * h / w)
    assert plane["eye_mm"] is None and plane["lineup_px"] is None
    for args, says in ((["nope.png"], "no such image"), ([str(REPO / "README.md")], "not an image"),
                       ([str(REPO / "examples" / "car.png"), "--width", "-1"], "not a positive size")):
        bad = run_cli("photo-plane", *args)
        lines = bad.stderr.strip().splitlines()
        assert bad.returncode == 2 and len(lines) == 1 and says in lines[0] and not bad.stdout
