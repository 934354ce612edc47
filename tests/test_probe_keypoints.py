"""The keypoint probe's training data and read-out: each render's keypoints sit where that render
shows them, a mirrored picture names them as the other half, and a heat map's peak reads back its
point."""
from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from tests.conftest import REPO


@pytest.fixture(scope="module")
def probe():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import probe_keypoints

    return probe_keypoints


def test_each_renders_keypoints_lie_in_the_cars_box_and_show_one_side_of_it(probe, tmp_path):
    assert probe.render(tmp_path, images_per_body=4, max_bodies=1) == 4
    names = probe.keypoint_names()
    for picture in sorted(tmp_path.glob("*.jpg")):
        meta = json.loads(picture.with_suffix(".json").read_text())
        x0, y0, x1, y1 = meta["box"]
        points = meta["keypoints"]
        assert len(points) >= 10 and set(points) <= set(names)
        uv = np.array(list(points.values()))
        assert (uv[:, 0] >= x0 - 2).all() and (uv[:, 0] <= x1 + 2).all()
        assert (uv[:, 1] >= y0 - 2).all() and (uv[:, 1] <= y1 + 2).all()
        # a view shows the side arches of one half only (a front or rear view none of them)
        arches = {n for n in points if "arch" in n}
        assert not ({n for n in arches if n.endswith("_right")} and {n for n in arches if not n.endswith("_right")})


def test_a_mirrored_picture_names_each_keypoint_as_its_other_half(probe):
    names = probe.keypoint_names()
    assert len(names) == 62
    assert probe.twin("front_arch_top", names) == "front_arch_top_right"
    assert probe.twin("front_arch_top_right", names) == "front_arch_top"
    assert probe.twin("nose_centre", names) == "nose_centre"  # on the plane of symmetry
    assert sorted(probe.twin(n, names) for n in names) == sorted(names)


def test_the_heat_maps_peak_where_their_points_are_and_a_peak_reads_back_its_point(probe):
    names = probe.keypoint_names()
    points = {"nose_centre": (20.3, 31.7), "rear_arch_top_right": (70.8, 50.2)}
    maps = probe.heat_maps(points, names, probe.MAP_PX)
    assert maps.shape == (62, probe.MAP_PX, probe.MAP_PX) and maps.max() == 1.0
    uv, height = probe.peaks(maps)
    for name, point in points.items():
        k = names.index(name)
        assert np.allclose(uv[k], point, atol=0.5) and height[k] == 1.0  # the target's peak pixel
    assert np.count_nonzero(height) == 2  # the other maps are empty
    # a network's smooth peak (no pixel set to 1) reads back to a hundredth of a pixel
    grid = np.arange(probe.MAP_PX) + 0.5
    u, v = 40.37, 12.81
    smooth = np.exp(-((grid[None, :] - u) ** 2 + (grid[:, None] - v) ** 2) / (2 * probe.SIGMA_PX ** 2))
    assert np.allclose(probe.peaks(0.8 * smooth[None])[0][0], (u, v), atol=0.01)
