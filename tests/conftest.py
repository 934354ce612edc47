"""Shared fixtures. The library cache goes to a per-session temporary folder."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory):
    os.environ["CARBODY_CACHE_DIR"] = str(tmp_path_factory.mktemp("cache"))
    yield


@pytest.fixture(scope="session")
def topology():
    from carbody.topology import load_topology

    return load_topology()


@pytest.fixture(scope="session")
def templates():
    from carbody.templates import load_templates

    return load_templates()


@pytest.fixture(scope="session")
def library():
    from carbody.library import load_library

    return load_library()


@pytest.fixture(scope="session")
def example_reconstruction():
    """``carbody.reconstruct`` of the shipped example (told 30°), once per test process."""
    import carbody

    examples = REPO / "examples"
    return carbody.reconstruct(examples / "car.png", examples / "car_keypoints.json", view=30)


@pytest.fixture(scope="session")
def first_library(library):
    """The library of the first round's 14 templates (the manifest's first 14): there the pickup,
    the roadster and the MPV each have no sibling, as the tests of what the fit does for a car
    unlike every template need (the 33 templates now hold other pickups, vans and city cars)."""
    names = library.template_names
    assert names[13] == "Chrysler Pacifica", names[:14]
    return library.without(*names[14:])


@pytest.fixture
def template_copy(tmp_path):
    """A writable copy of the shipped template folder."""
    from carbody.templates import templates_dir

    dst = tmp_path / "templates_step"
    shutil.copytree(templates_dir(), dst)
    return dst


def run_cli(*args: str, check: bool = False) -> subprocess.CompletedProcess:
    """Run ``carbody ARGS`` in a subprocess (the real console entry point's module)."""
    proc = subprocess.run([sys.executable, "-m", "carbody", *args], capture_output=True, text=True,
                          cwd=REPO, env={**os.environ})
    if check and proc.returncode != 0:
        raise AssertionError(f"carbody {' '.join(args)} failed ({proc.returncode}):\n{proc.stderr}")
    return proc


def off_centre_photo(truth, view, noise: float = 0.0, focal: float = 900.0):
    """{name: [u, v]} of a normalised car photographed from 2200 units (≈ 6 m) by a pinhole
    camera of focal length ``focal`` px whose axis, through the centre of a 2000 × 1000 px photo,
    points 15° to the car's right of it (only what that camera sees)."""
    import numpy as np

    from carbody.camera import View, view_rotation
    from carbody.fit.visibility import visible_slots

    both = np.concatenate([truth, truth * [-1, 1, 1]])
    centre = (both.min(axis=0) + both.max(axis=0)) / 2
    d, r, w = view_rotation(view)
    eye, turn = centre + 2200.0 * d, np.radians(15.0)
    axis, right = -np.cos(turn) * d + np.sin(turn) * r, np.cos(turn) * r + np.sin(turn) * d
    slots = visible_slots(View(view.azimuth, view.elevation, 0, 2200.0, tuple(centre)), truth)
    q = np.array([truth[s.point_index] * s.sign for s in slots]) - eye
    uv = np.array([1000.0, 500.0]) + focal * np.stack([q @ right, -(q @ w)], axis=1) / (q @ axis)[:, None]
    uv += np.random.default_rng(0).normal(0.0, noise, uv.shape)
    return {s.name: [float(u), float(v)] for s, (u, v) in zip(slots, uv)}


def camera_jpeg(path, size=(2000, 1000), focal_35mm: int = 17):
    """A blank JPEG as a camera writes it: EXIF with its 35 mm-equivalent focal length and its
    own pixel size (the photo is uncropped). Returns the focal length in pixels."""
    import math

    from PIL import Image

    from carbody.fit.focal import FILM_DIAGONAL_MM

    exif = Image.Exif()
    ifd = exif.get_ifd(0x8769)
    ifd[0xA405], ifd[0xA002], ifd[0xA003] = focal_35mm, *size
    Image.new("RGB", size, (200, 200, 200)).save(path, exif=exif)
    return focal_35mm * math.hypot(*size) / FILM_DIAGONAL_MM
