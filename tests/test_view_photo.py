"""Photo-like renders: a person's camera, the ground, environment-lit paint, artefacts."""
from __future__ import annotations

import numpy as np
import pytest


def test_person_camera_stands_3_to_15_m_away_at_a_persons_height():
    from carbody.view.photo import person_camera

    rng = np.random.default_rng(0)
    lo, hi, ground = np.array([-900.0, -900, -330]), np.array([900.0, 3600, 1150]), -330.0
    centre = (lo + hi) / 2
    for _ in range(200):
        el, dist = person_camera(rng, lo, hi, ground, radius=2500.0)
        height = centre[2] + dist * np.sin(np.radians(el)) - ground
        horizontal = dist * np.cos(np.radians(el))
        assert 399 <= height <= 3501 and 2999 <= horizontal <= 15001
        assert -10 < el < 45


def test_environment_mirrors_the_horizon_in_a_cars_flank():
    from carbody.render import Environment
    from carbody.render.scene import environment_shading

    z = np.linspace(-1000, 1000, 21)
    pts = np.c_[np.zeros_like(z), np.zeros_like(z), z]
    normals = np.tile([1.0, 0, 0], (len(z), 1))
    env = Environment(sky=(0.9, 0.9, 0.95), ground=(0.15, 0.15, 0.15), paint_reflectance=0.3, sun=0.0)
    rgb = environment_shading(pts, normals, np.array([4000.0, 0, 0]), np.array([0.1, 0.1, 0.1]), env,
                              glass=False, specular=0.0)
    above, below = rgb[z > 100].mean(), rgb[z < -100].mean()
    assert above > below + 0.1                   # sky above the eye line, ground below it
    glass = environment_shading(pts, normals, np.array([4000.0, 0, 0]), np.array([0.05, 0.05, 0.05]), env,
                                glass=True, specular=0.0)
    assert glass[z < -100].mean() < 0.2          # the dark cabin shows where the ground is mirrored


def test_artefacts_keep_the_picture_and_add_jpeg_noise():
    from carbody.view.photo import artefacts

    img = np.zeros((128, 128, 3), np.uint8)
    img[32:96, 32:96] = 200
    out = artefacts(img, np.random.default_rng(3))
    assert out.shape == img.shape and out.dtype == np.uint8
    assert 0 < np.abs(out.astype(int) - img).mean() < 25


@pytest.fixture(scope="module")
def box_scene():
    import cadquery as cq

    from carbody.render import Scene, tessellate

    box = cq.Workplane("XY").box(1800, 4500, 1400).translate((0, 2000, 400)).val()
    return Scene(tessellate(box), size=(128, 128))


def test_a_photo_like_shot_has_ground_under_the_car_and_follows_its_seed(box_scene):
    from carbody.view.dataset import BodySpec, Variation, shoot_photo
    from carbody.view.photo import PhotoLook

    spec = BodySpec("box", "box", 0, (1, 1, 1, 1), np.zeros((280, 3)), tyre_radius_mm=300.0)
    on = Variation(photo=PhotoLook())
    shot, a = shoot_photo(box_scene, spec, 6, np.random.default_rng(5), on)
    _, b = shoot_photo(box_scene, spec, 6, np.random.default_rng(5), on)
    assert np.array_equal(a, b) and a.shape == (128, 128, 3)
    assert shot.theta_deg == pytest.approx(90, abs=3.01) and -10 < shot.elevation_deg < 35
    off = Variation(photo=PhotoLook(ground=False, artefacts=False))
    _, c = shoot_photo(box_scene, spec, 6, np.random.default_rng(5), off)
    assert np.abs(a[-8:].astype(int) - c[-8:]).mean() > 5      # the bottom of the frame is ground


def test_a_framed_shot_stores_the_cars_box_with_room_round_it(box_scene):
    from carbody.view.dataset import BodySpec, Variation, shoot_photo
    from carbody.view.photo import EARLIER_PHOTO_LOOK, PhotoLook

    spec = BodySpec("box", "box", 0, (1, 1, 1, 1), np.zeros((280, 3)), tyre_radius_mm=300.0)
    for k in (0, 3, 6, 9, 15):
        shot, img = shoot_photo(box_scene, spec, k, np.random.default_rng(k), Variation(photo=PhotoLook()))
        x0, y0, x1, y1 = shot.box
        assert 0 <= x0 < x1 <= 128 and 0 <= y0 < y1 <= 128
        assert 0.5 * 128 < max(x1 - x0, y1 - y0) < 0.85 * 128          # the crop's square fits the render
    shot, _ = shoot_photo(box_scene, spec, 6, np.random.default_rng(1), Variation(photo=EARLIER_PHOTO_LOOK))
    assert shot.box is None


def test_the_photographer_stands_clear_of_the_bumper():
    from carbody.view.photo import person_camera

    rng = np.random.default_rng(0)
    lo, hi, ground = np.array([-900.0, -900, -330]), np.array([900.0, 3600, 1150]), -330.0
    for theta in (0.0, 30.0, 90.0, 180.0):
        for _ in range(100):
            el, dist = person_camera(rng, lo, hi, ground, radius=2500.0, theta_deg=theta)
            horizontal = dist * np.cos(np.radians(el))
            t = np.radians(theta)
            near = abs(np.cos(t)) * (hi - lo)[1] / 2 + abs(np.sin(t)) * (hi - lo)[0] / 2
            assert 999 < horizontal - near < 14001


def test_a_photo_frame_crop_frames_the_box_and_repeats_the_frames_edges():
    from carbody.view.photo import photo_frame_crop

    img = np.zeros((128, 128, 3), np.uint8)
    img[:, :, 1] = np.arange(128, dtype=np.uint8)[:, None]      # a vertical ramp: rows tell where we are
    img[50:80, 24:104, 0] = 255                                  # the car: 80 x 30 px
    widths, flat_rows = [], 0
    for seed in range(40):
        out = photo_frame_crop(img, (24, 50, 104, 80), np.random.default_rng(seed), 64)
        assert out.shape == (64, 64, 3) and out.dtype == np.uint8
        cols = np.nonzero((out[..., 0] > 128).any(axis=0))[0]
        widths.append((np.ptp(cols) + 1) / 64)
        # past a frame's top or bottom edge the crop repeats the edge row
        flat_rows += int((np.abs(np.diff(out[:, :, 1].astype(int), axis=0)) == 0).all(axis=1)[:4].all())
    assert 0.65 < np.median(widths) < 0.9                         # the box spans ~80 % of the square
    assert flat_rows > 5                                          # some frames cut above the car


def test_details_lie_on_a_curved_tail_not_behind_it():
    """A tail bulging backward (a half cylinder): the lamp sheets follow it within their lift."""
    from carbody.render.mesh import FaceMesh
    from carbody.view.dataset import _surface_patch

    r = 900.0
    a, z = np.meshgrid(np.linspace(0, np.pi / 2, 30), np.linspace(0, 600, 12))
    x, y = r * np.sin(a), 4000 + 300 * np.cos(a)                # x 0..900, y bulges to 4300 at x = 0
    v = np.c_[x.ravel(), y.ravel(), z.ravel()]
    i, k = np.meshgrid(np.arange(11), np.arange(29), indexing="ij")
    f = (i * 30 + k).ravel()
    tail = FaceMesh("tail", v, np.r_[np.c_[f, f + 1, f + 30], np.c_[f + 1, f + 31, f + 30]])
    patch = _surface_patch("taillight", [tail], 0.5, 0.98, 0.1, 0.4, out_y=1.0, lift=4.0)
    px = patch.vertices[np.unique(patch.triangles)]
    t = np.linspace(0, np.pi / 2, 4000)
    curve = np.c_[r * np.sin(t), 4000 + 300 * np.cos(t)]
    gap = np.linalg.norm(px[:, None, :2] - curve[None], axis=2).min(axis=1)
    assert np.all((gap > 2.0) & (gap < 6.0))                    # 4 mm off the surface (chords aside)
    assert px[:, 0].max() > 0.9 * r and px[:, 2].min() > 350 and px[:, 2].max() < 545


def test_tone_encodes_light_as_a_camera_does():
    from carbody.render import Environment, Look
    from carbody.view.photo import display_encode, linear_look

    look = linear_look(Look(paint=(0.5, 0.5, 0.5), colours={"tyre": (1.0, 0.0, 0.0)}, environment=Environment()))
    assert look.paint[0] == pytest.approx(0.5 ** 2.2) and look.colours["tyre"] == (1.0, 0.0, 0.0)
    assert look.environment.sky[0] == pytest.approx(0.75 ** 2.2)
    light = np.array([[[0.28 * 255] * 3, [0.0] * 3, [128.0] * 3]], dtype=np.uint8)   # a white car's shaded flank
    alpha = np.array([[1.0, 1.0, 0.5]])
    shown = display_encode(light, alpha, exposure=1.0)
    assert 135 < shown[0, 0, 0] < 150 and shown[0, 1, 0] == 0          # 0.28 of white shows as ~0.56
    assert shown[0, 2, 0] == pytest.approx(255 * 0.5, abs=2)            # edge pixels keep their coverage


def test_plates_come_in_the_worlds_colours():
    from carbody.view.photo import PhotoLook, photo_looks

    rng = np.random.default_rng(0)
    plates = np.array([photo_looks(rng, PhotoLook(plate_colours=True))[2]["plate"] for _ in range(200)])
    red = (plates[:, 0] > 0.5) & (plates[:, 1] < 0.3)
    yellow = (plates[:, 0] > 0.6) & (plates[:, 1] > 0.5) & (plates[:, 2] < 0.3)
    assert 10 < red.sum() < 60 and 10 < yellow.sum() < 60
    white = np.array([photo_looks(rng, PhotoLook(plate_colours=False))[2]["plate"] for _ in range(50)])
    assert white.min() > 0.6                                   # without: white plates only
