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
