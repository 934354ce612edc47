"""The tyre probe's training data: each render's wheel mask is the wheels that render shows."""
from __future__ import annotations

import sys

import numpy as np
import pytest

from tests.conftest import REPO


@pytest.fixture(scope="module")
def probe():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import probe_tyres

    return probe_tyres


def test_each_renders_wheel_mask_covers_its_dark_tyres_inside_the_cars_box(probe, tmp_path):
    import cv2

    assert probe.render(tmp_path, images_per_body=3, max_bodies=1) == 3
    for picture in sorted(tmp_path.glob("*.jpg")):
        image = cv2.imread(str(picture), cv2.IMREAD_GRAYSCALE).astype(float)
        mask = cv2.imread(str(picture).replace(".jpg", "_mask.png"), cv2.IMREAD_GRAYSCALE) > 127
        x0, y0, x1, y1 = (int(round(float(v))) for v in picture.with_suffix(".box").read_text().split())
        car = np.zeros_like(mask)
        car[y0:y1, x0:x1] = True
        assert mask.any() and not (mask & ~car).any()          # wheels, all on the car
        assert 0.005 < mask.sum() / car.sum() < 0.25           # a share of the car, not all of it
        # the mask sits on the wheels, mirrored shots too: tyres are darker than the car round them
        assert image[mask].mean() < image[car & ~mask].mean()


def test_the_crop_maps_the_cars_box_into_the_networks_square(probe):
    image = np.zeros((300, 500, 3), np.uint8)
    crop, M = probe.square_crop(image, (100, 50, 400, 200), margin=0.25)
    assert crop.shape == (probe.INPUT_PX, probe.INPUT_PX, 3)
    corners = np.array([[100, 50, 1], [400, 200, 1]], float) @ M.T
    assert corners[:, 0] == pytest.approx([16.0, 144.0])  # the longer side spans 1 / 1.25 of it
    assert corners.mean(axis=0) == pytest.approx([80.0, 80.0])


def test_varied_rims_stay_on_their_wheels_and_keep_a_dark_gap_behind_the_spokes(probe):
    from carbody.library import load_library
    from carbody.view.dataset import wheel_meshes

    library = load_library()
    wheels = wheel_meshes(library.points(library.original(0)) * 2.7, tyre_radius_mm=320.0)
    discs = [m for m in wheels if m.name == "rim"]
    centres = np.array([m.vertices[-1] for m in discs])
    radius = np.linalg.norm(discs[0].vertices[0, 1:] - centres[0, 1:])
    varied = probe.varied_rims(wheels, np.random.default_rng(1))
    added = [m for m in varied if all(m is not w for w in wheels)]
    rims = [m for m in added if m.name in ("rim", "wheel_paint")]
    gaps = [m for m in added if m.name == "tyre"]
    assert len(rims) > len(discs) and gaps  # spokes, lips and hubs over a dark gap, not four discs
    for m in rims + gaps:
        d = np.linalg.norm(m.vertices[:, None, :] - centres[None], axis=2).min(axis=1)
        assert (d <= radius + 3.0).all()  # on a wheel, within its rim
    assert all(any(m is w for m in varied) for w in wheels if w.name != "rim")  # tyres and wells kept


def test_a_tyre_near_a_wheel_found_moves_onto_it_and_takes_its_hub_along(probe):
    seen = np.array([[100.0, 200.0], [300.0, 200.0], [500.0, 210.0], [700.0, 210.0]])
    hubs = seen - [0.0, 12.0]  # each hub above its visible tyre's centroid
    found = np.array([[104.0, 203.0], [520.0, 230.0], [900.0, 100.0]])
    tyres, centres = probe.onto_wheels_found(seen, hubs, found, near_px=10.0)
    assert np.allclose(tyres[0], found[0]) and np.allclose(centres[0], found[0] - [0.0, 12.0])
    assert np.allclose(tyres[1:], seen[1:]) and np.allclose(centres[1:], hubs[1:])  # none within 10 px
    tyres, _ = probe.onto_wheels_found(seen, hubs, found, near_px=30.0)
    assert np.allclose(tyres[2], found[1])
    assert np.allclose(probe.onto_wheels_found(seen, hubs, np.zeros((0, 2)), 30.0)[0], seen)  # nothing found
