"""The camera contract of SPEC "Frames and units" and the paper's eq. 1."""
import numpy as np
import pytest

from carbody.errors import AngleError
from carbody.camera import (View, camera_direction, check_azimuth, eq1_angles, eq1_rotation,
                                mirror_view, project, view_rotation)

NOSE = np.array([0.0, -900.0, 300.0])   # ahead of the front wheel
TAIL = np.array([0.0, 1900.0, 300.0])
LEFT = np.array([800.0, 500.0, 300.0])  # on the car's left side


def test_side_view_puts_the_nose_left_and_up_up():
    v = View(90)
    nose, tail, top = project(np.array([NOSE, TAIL, [0, 0, 1000.0]]), v)
    assert nose[0] < tail[0]
    assert top[1] < nose[1]  # v grows downward
    np.testing.assert_allclose(eq1_rotation(0, 0, 0), view_rotation(v), atol=1e-12)


@pytest.mark.parametrize("azimuth,toward", [(0, [0, -1, 0]), (90, [1, 0, 0]), (180, [0, 1, 0]), (270, [-1, 0, 0])])
def test_camera_direction_at_the_four_sides(azimuth, toward):
    np.testing.assert_allclose(camera_direction(View(azimuth)), toward, atol=1e-12)


def test_front_view_shows_the_left_side_on_image_right():
    (u_left, _), (u_centre, _) = project(np.array([LEFT, [0, 500, 300.0]]), View(0))
    assert u_left > u_centre


def test_elevation_looks_down_on_the_roof():
    d = camera_direction(View(30, 20))
    assert d[2] == pytest.approx(np.sin(np.radians(20)))
    rot = view_rotation(View(30, 20))
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(rot) == pytest.approx(1.0)


@pytest.mark.parametrize("seed", range(5))
def test_eq1_angles_reproduce_the_view(seed):
    rng = np.random.default_rng(seed)
    v = View(rng.uniform(0, 360), rng.uniform(-40, 60), rng.uniform(-20, 20))
    np.testing.assert_allclose(eq1_rotation(*eq1_angles(v)), view_rotation(v), atol=1e-10)


def test_mirror_view_flips_the_image_of_the_mirrored_car():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(20, 3)) * 500
    v = View(35, 12, 4)
    a = project(pts, v)
    b = project(pts * [-1, 1, 1], mirror_view(v))
    np.testing.assert_allclose(a[:, 0], -b[:, 0], atol=1e-9)
    np.testing.assert_allclose(a[:, 1], b[:, 1], atol=1e-9)


@pytest.mark.parametrize("bad", [-1, 360.5, "abc", float("nan"), None])
def test_view_outside_0_360_is_refused(bad):
    with pytest.raises(AngleError):
        check_azimuth(bad)
    assert check_azimuth(360) == 360.0


@pytest.mark.parametrize("theta,other", [(30, 32), (150, 147), (60, 70)])
def test_level_view_cannot_tell_azimuth_from_width_and_height(theta, other):
    """Why a level photo does not fix the azimuth: the car seen at θ and the car made
    tan θ'/tan θ as wide and sin θ'/sin θ as tall (wheelbase unchanged) seen at θ' give the same
    image, pixel for pixel. A camera 10° above the car tells them apart."""
    car = np.random.default_rng(theta).uniform([-900, -1000, -300], [900, 2000, 1200], (50, 3))
    t, o = np.radians(theta), np.radians(other)
    twin = car * [np.tan(o) / np.tan(t), 1.0, np.sin(o) / np.sin(t)]
    scale, offset = 0.3, (500.0, 300.0)
    seen = project(car, View(theta), scale, offset)
    np.testing.assert_allclose(project(twin, View(other), scale * np.sin(t) / np.sin(o), offset), seen,
                               atol=1e-9)
    # From 10° above, no image scale and offset maps the twin onto the car.
    target = project(car, View(theta, 10.0), scale, offset)
    unit = project(twin, View(other, 10.0))
    A = np.zeros((2 * len(car), 3))
    A[0::2, 0], A[1::2, 0], A[0::2, 1], A[1::2, 2] = unit[:, 0], unit[:, 1], 1.0, 1.0
    fit, *_ = np.linalg.lstsq(A, target.ravel(), rcond=None)
    assert np.sqrt(np.mean((A @ fit - target.ravel()) ** 2)) > 1.0


def test_pinhole_view_shows_nearer_points_larger_and_tends_to_orthographic():
    """A pinhole view magnifies what is nearer the camera; far away it is the orthographic one."""
    from carbody.camera import perspective_factors

    view = View(90, 10, 0, 6000.0, (0.0, 1400.0, 500.0))
    near, far = np.array([900.0, 1400.0, 500.0]), np.array([-900.0, 1400.0, 500.0])
    k = perspective_factors(np.stack([near, far]), view)
    assert k[0] > 1.0 > k[1]
    aim = project(np.array(view.aim), view, 0.5, (100, 200))
    np.testing.assert_allclose(aim, project(np.array(view.aim), View(90, 10), 0.5, (100, 200)))
    distant = View(90, 10, 0, 1e12, view.aim)
    pts = np.random.default_rng(0).uniform(-2000, 2000, (20, 3))
    np.testing.assert_allclose(project(pts, distant, 0.5), project(pts, View(90, 10), 0.5), atol=1e-4)
    # The mirrored car in the mirrored pinhole view is the mirrored picture.
    m = mirror_view(view)
    np.testing.assert_allclose(project(pts * [-1, 1, 1], m)[:, 0], -project(pts, view)[:, 0], atol=1e-9)


def test_camera_inside_the_car_is_refused():
    from carbody.camera import perspective_factors

    with pytest.raises(AngleError, match="inside"):
        perspective_factors(np.array([[0.0, 3000.0, 0.0]]), View(180, 0, 0, 1000.0))
    with pytest.raises(AngleError, match="positive"):
        View(30, 0, 0, -5.0)


def test_look_at_homography_turns_the_camera_to_a_point():
    from carbody.camera import apply_homography, look_at_homography

    principal, target = np.array([640.0, 360.0]), np.array([1000.0, 200.0])
    H = look_at_homography(target, principal, 900.0)
    assert np.allclose(apply_homography(H, target), principal)
    assert np.allclose(look_at_homography(principal, principal, 900.0), np.eye(3))
    # A rotation about the camera centre: the angle between any two rays is kept.
    a, b = np.array([100.0, 50.0]), np.array([1200.0, 700.0])

    def ray(p):
        v = np.append((p - principal) / 900.0, 1.0)
        return v / np.linalg.norm(v)

    Ha, Hb = apply_homography(H, a), apply_homography(H, b)
    assert ray(a) @ ray(b) == pytest.approx(ray(Ha) @ ray(Hb), abs=1e-12)
