"""The shipped view classifier: loads from the package with no download and tells the view of
fresh renders of a car it never saw in training within ±15°."""
from __future__ import annotations

import numpy as np
import pytest

from carbody.view.labels import angular_difference
from carbody.view.predict import SHIPPED_WEIGHTS
from tests.conftest import run_cli

pytestmark = pytest.mark.skipif(not SHIPPED_WEIGHTS.is_file(), reason="no shipped weights in the package")


def _scene(templates, name):
    """A scene of template ``name``, surfaced by our pipeline, with wheels."""
    from carbody.render import Scene, tessellate
    from carbody.surface import build_body
    from carbody.view.dataset import wheel_meshes

    row, wf = next((r, w) for r, w in templates if r["name"] == name)
    meshes = tessellate(build_body(wf, check=False)) + wheel_meshes(wf.control_points, float(row["tyre_radius_mm"]))
    return Scene(meshes, size=(160, 120))


@pytest.fixture(scope="module")
def held_out_cars(templates):
    """(name, scene) of every template the shipped weights held out of their training."""
    from carbody.view.predict import load_classifier

    _, meta = load_classifier()
    held_out = meta["dataset"]["validation_templates"]
    assert held_out, "the shipped weights name their held-out cars"
    return [(name, _scene(templates, name)) for name in held_out]


@pytest.fixture(scope="module")
def held_out_scene(held_out_cars):
    name, scene = held_out_cars[0]
    return scene, name


def test_shipped_weights_are_small_and_load_without_download():
    from carbody.view.predict import load_classifier

    assert SHIPPED_WEIGHTS.stat().st_size < 6_000_000
    model, meta = load_classifier()
    assert meta["num_classes"] == 24 and meta["input_size"] == 128
    assert len(meta["history"]["val_acc"]) >= 1


def test_fresh_renders_of_the_held_out_cars_are_classified_within_15_degrees(held_out_cars):
    """Each held-out car at four views, the whole picture (no box, one look): at least 26 of the
    28 within ±15° (the renders' benchmark: 97.5 %). The cab-over van (Daihatsu Hijet Cargo)
    is the hard one: its flat front reads as a rear at 30° to these weights, with or without a box."""
    from carbody.render import Look
    from carbody.view.predict import predict_view

    look = Look(paint=(0.75, 0.1, 0.1), background=(0.85, 0.87, 0.9),
                colours={"tyre": (0.05, 0.05, 0.05), "rim": (0.6, 0.6, 0.6)})
    misses = []
    for name, scene in held_out_cars:
        for theta, elevation in [(30, 10), (90, 5), (150, 15), (300, 20)]:
            render_theta, flip = (360 - theta, True) if theta > 180 else (theta, False)
            img = scene.render(render_theta, elevation, look=look, distance=None, fill=0.85)
            if flip:
                img = img[:, ::-1].copy()
            p = predict_view(img)
            if angular_difference(p.theta_deg, theta) > 15:
                misses.append(f"{name} at {theta}°: {p.theta_deg:.0f}°")
    assert len(held_out_cars) == 7 and len(misses) <= 2, misses


def test_view_cli_prints_class_and_json(held_out_scene, tmp_path):
    import json

    from carbody.render import save_png

    scene, _ = held_out_scene
    save_png(scene.render(90, 5), tmp_path / "side.png")
    gray = scene.render(90, 5).mean(axis=2).astype(np.uint8)
    save_png(gray, tmp_path / "side_gray.png")
    out = run_cli("view", str(tmp_path / "side.png"), "--json", check=True)
    data = json.loads(out.stdout)
    assert set(data) >= {"class_deg", "theta_deg", "probabilities", "side"}
    assert sum(data["probabilities"].values()) == pytest.approx(1, abs=1e-3)
    out = run_cli("view", str(tmp_path / "side_gray.png"), check=True)
    assert out.stdout.startswith("view ")
