"""Every bad input is one line on stderr and exit code 2, checked before the work; the Python API
raises a CarbodyError subclass for the same inputs, never a bare ValueError, TypeError or
AttributeError."""
from __future__ import annotations

import json
import os
import re
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from carbody.errors import CarbodyError, ImageError, KeypointError, TemplateError
from tests.conftest import REPO

EXAMPLES = REPO / "examples"
PHOTO, KEYPOINTS = EXAMPLES / "car.png", EXAMPLES / "car_keypoints.json"
MARKS = json.loads(KEYPOINTS.read_text())
WIRE = REPO / "templates_step" / "volvo_v60.step"


def refused(capsys, *argv: str) -> str:
    """The one line ``carbody ARGV`` (run in this process) refuses with, exit code 2 asserted."""
    from carbody.cli import main

    code = main([*map(str, argv), "--quiet"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1, lines
    return lines[0]


def fit_refuses(capsys, tmp_path, keypoints, image=PHOTO, *more) -> str:
    """The line ``carbody fit`` refuses ``keypoints`` (a path, or data written as JSON) with."""
    if not isinstance(keypoints, (str, Path)):
        path = tmp_path / "k.json"
        path.write_bytes(keypoints if isinstance(keypoints, bytes) else json.dumps(keypoints).encode())
        keypoints = path
    line = refused(capsys, "fit", image, "-k", keypoints, "--view", "30", "--no-refine", "-o", tmp_path / "w.step", *more)
    assert not (tmp_path / "w.step").exists()
    return line


def project(**fields) -> dict:
    return {**MARKS, **fields}


def with_mark(value) -> dict:
    return project(keypoints={**MARKS["keypoints"], "nose_centre": value})


def coco(**changes) -> dict:
    names = list(MARKS["keypoints"])
    data = {"images": [{"id": 1, "file_name": "car.png", "width": 1000, "height": 640}],
            "categories": [{"id": 1, "name": "car", "keypoints": names}],
            "annotations": [{"image_id": 1, "category_id": 1,
                             "keypoints": [c for n in names for c in (*MARKS["keypoints"][n], 2)]}]}
    for path, value in changes.items():
        *keys, last = path.split(".")
        target = data
        for k in keys:
            target = target[int(k)] if k.isdigit() else target[k]
        target[int(last) if last.isdigit() else last] = value
    return data


def labelme(**fields) -> dict:
    return {"imagePath": "car.png", "imageWidth": 1000, "imageHeight": 640,
            "shapes": [{"label": n, "points": [p], "shape_type": "point"} for n, p in MARKS["keypoints"].items()],
            **fields}


@pytest.mark.parametrize("data, says", [
    (project(image_size="1000x640"), "'image_size': expected [width, height] pixels, got '1000x640'"),
    (project(image_size=[1000, 640, 3]), "'image_size': expected [width, height]"),
    (project(image_size={"w": 1000}), "'image_size': expected [width, height]"),
    (project(image_size=[1000.5, 640]), "whole numbers of pixels"),
    (b'{"image_size": [Infinity, 640], "keypoints": {"nose_centre": [1, 2]}}', "whole numbers of pixels"),
    (with_mark("28"), "keypoint 'nose_centre': expected [u, v] pixels, got '28'"),
    (with_mark(["283", "310"]), "as two numbers"),
    (with_mark([True, False]), "as two numbers"),
    (with_mark([1, 2, 3]), "expected [u, v] pixels, got [1, 2, 3]"),
    (with_mark({"u": 1, "v": 2}), "expected [u, v] pixels"),
    (project(image=["car.png"]), "'image' must be a file name"),
    (coco(categories="car"), "'categories' must be a list of categories"),
    (coco(annotations={"0": 1}), "'annotations' must be a list of annotations"),
    (coco(images="car.png"), "'images' must be a list of images"),
    (coco(**{"annotations.0.keypoints": "1 2 2"}), "'keypoints' must be a list of u, v, flag numbers"),
    (coco(**{"categories.0.keypoints": "nose_centre"}), "the category's list of keypoint names"),
    (coco(**{"categories.0.keypoints.0": 7}), "keypoint names must be strings"),
    (coco(**{"annotations.0.keypoints.0": "283"}), "as two numbers"),
    (coco(**{"annotations.0.keypoints.2": "2"}), "visibility flag: expected a number, got '2'"),
    (coco(**{"images.0.width": "1000"}), "the image's 'width' and 'height'"),
    (coco(**{"annotations.0": [1, 2]}), "every one of 'annotations' must be an object"),
    (labelme(shapes=["nose_centre"]), "every one of 'shapes' must be an object"),
    (labelme(shapes=[{"label": ["nose_centre"], "points": [[1, 2]]}]), "'label' must be a keypoint name"),
    (labelme(shapes=[{"label": "nose_centre", "points": {"u": 1}}]), "must hold one [u, v]"),
    (labelme(shapes=[{"label": "nose_centre", "points": [["1", "2"]]}]), "as two numbers"),
    (labelme(imageWidth=1e400), "'imageWidth' and 'imageHeight'"),
    (b"[" * 100_000 + b"]" * 100_000, "nested too deeply"),
    (b'{"keypoints": ' + b"[" * 100_000, "nested too deeply"),
    (b'{"keypoints": {"nose_centre": [1, 2], "nose_centre": [3, 4]}}', "'nose_centre' is given twice"),
    (b"\xff\xfe{}", "is not UTF-8 text"),
])
def test_a_keypoint_file_of_the_wrong_shape_is_one_line(capsys, tmp_path, data, says):
    from carbody.fit.keypoints_io import read_keypoints

    assert says in fit_refuses(capsys, tmp_path, data)
    with pytest.raises(KeypointError):  # the API: the same, typed
        read_keypoints(tmp_path / "k.json")


def test_a_keypoint_file_with_a_byte_order_mark_is_read(tmp_path):
    from carbody.fit.keypoints_io import read_keypoints

    path = tmp_path / "k.json"
    path.write_bytes(b"\xef\xbb\xbf" + KEYPOINTS.read_bytes())
    ann = read_keypoints(path)
    assert ann.image_size == (1000, 640) and len(ann.points) == len(MARKS["keypoints"])


def test_a_hundred_thousand_names_are_refused_by_the_first_unknown_and_by_the_repeat(capsys, tmp_path):
    """Distinct names (the fit names the first unknown one) and one name given twice at the end
    (found without comparing every pair: that took minutes)."""
    names = {f"mark_{i}": [1.0, 2.0] for i in range(100_000)}
    assert "unknown keypoint name 'mark_0'" in fit_refuses(capsys, tmp_path, {"keypoints": names})
    text = json.dumps({"keypoints": names})[:-2] + ', "mark_5": [1, 2]}}'
    assert "'mark_5' is given twice" in fit_refuses(capsys, tmp_path, text.encode())


def test_a_huge_keypoint_file_or_a_device_is_refused_by_its_size_before_parsing(capsys, tmp_path):
    from carbody.fit.keypoints_io import read_keypoints
    from carbody.inputs import MAX_JSON_BYTES

    big = tmp_path / "big.json"
    with open(big, "wb") as f:  # sparse: 200 MB on paper, nothing on disk
        f.truncate(200 * 2**20)
    assert f"200 MB is larger than any keypoint file ({MAX_JSON_BYTES // 2**20} MB at most)" in \
        fit_refuses(capsys, tmp_path, big)
    assert "/dev/zero: not a regular file" in fit_refuses(capsys, tmp_path, "/dev/zero")
    with pytest.raises(KeypointError):
        read_keypoints("/dev/zero")


def png_header(width: int, height: int) -> bytes:
    """A PNG file that states a ``width`` x ``height`` picture (its pixels never follow: a
    decompression bomb's header, read without decoding)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b""))


@pytest.mark.parametrize("side", [100_000, 20_000])
def test_a_picture_above_the_pixel_limit_is_refused_from_its_header(capsys, tmp_path, side):
    from carbody.view.predict import MAX_IMAGE_PIXELS, read_image

    bomb = tmp_path / "bomb.png"
    bomb.write_bytes(png_header(side, side))
    line = fit_refuses(capsys, tmp_path, KEYPOINTS, bomb)  # its pixels never follow: read from the header
    assert f"more than the {MAX_IMAGE_PIXELS // 10**6} megapixels carbody reads" in line
    assert "megapixels" in refused(capsys, "photo-plane", bomb)
    assert "megapixels" in refused(capsys, "view", bomb)
    with pytest.raises(ImageError, match="megapixels"):
        read_image(bomb)


def test_a_folder_or_a_loop_of_links_is_refused_as_any_path(capsys, tmp_path):
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    folder = tmp_path / "folder"
    folder.mkdir()
    assert "a loop of symbolic links, not a keypoint file" in fit_refuses(capsys, tmp_path, loop)
    assert "is a folder, not a keypoint file" in fit_refuses(capsys, tmp_path, folder)
    assert "a loop of symbolic links, not an image file" in fit_refuses(capsys, tmp_path, KEYPOINTS, loop)
    assert "is a folder, not an image file" in fit_refuses(capsys, tmp_path, KEYPOINTS, folder)
    assert "a loop of symbolic links, not a STEP file" in refused(capsys, "surface", loop, "-o", tmp_path / "b.step")
    assert "is a folder, not a STEP file" in refused(capsys, "parts", folder)
    for out in (loop, loop / "w.step"):
        assert "a loop of symbolic links" in refused(capsys, "surface", WIRE, "-o", out)
    assert "is a folder" in refused(capsys, "surface", WIRE, "-o", folder)
    assert "not a regular file" in refused(capsys, "surface", WIRE, "-o", "/dev/null")
    assert "is a file" in refused(capsys, "reconstruct", PHOTO, "-k", KEYPOINTS, "-o", KEYPOINTS / "out")


@pytest.mark.parametrize("view, says", [
    ("front 999", "the angle after 'front' lies outside 0–180°"),
    ("rear -30", "the angle after 'rear' lies outside 0–180°"),
    ("999°", "outside 0–360°"),
    ("front nan", "not a finite angle"),
    ("upside down", "cannot read view"),
])
def test_a_view_out_of_range_is_one_line(capsys, tmp_path, view, says):
    assert says in fit_refuses(capsys, tmp_path, KEYPOINTS, PHOTO, "--view", view)
    assert says in refused(capsys, "reconstruct", PHOTO, "-k", KEYPOINTS, "--view", view, "-o", tmp_path / "r")
    assert not (tmp_path / "r").exists()


def test_a_step_coordinate_no_car_has_is_refused_naming_its_curve(capsys, tmp_path):
    from carbody.wireframe import read_wireframe

    text = WIRE.read_text()
    pole = re.search(r"B_SPLINE_CURVE_WITH_KNOTS\('',3,\(#(\d+),", text).group(1)
    text = re.sub(rf"#{pole} = CARTESIAN_POINT\('',\(([^,]+),", f"#{pole} = CARTESIAN_POINT('',(1.E300,", text)
    far = tmp_path / "far.step"
    far.write_text(text)
    says = "curve 'front_centre' has a control point at ["
    assert says in refused(capsys, "surface", far, "-o", tmp_path / "b.step")
    assert says in refused(capsys, "parts", far)
    assert says in refused(capsys, "fit", PHOTO, "-k", KEYPOINTS, "--view", "30", "-o", tmp_path / "w.step",
                           "--truth", far, "--report", tmp_path / "r.json")
    with pytest.raises(TemplateError, match="further than any car's"):
        read_wireframe(far)
    assert not any(p.suffix in (".step", ".json") and p != far for p in tmp_path.iterdir())


def test_parts_says_in_one_line_what_it_cannot_read(capsys, tmp_path):
    assert "not a readable STEP file" in refused(capsys, "parts", PHOTO)
    empty = tmp_path / "box.step"
    import cadquery as cq

    cq.exporters.export(cq.Workplane().box(1, 2, 3), str(empty))
    assert "names no curve and no face" in refused(capsys, "parts", empty)


def test_a_damaged_library_cache_is_rebuilt_and_an_unwritable_one_skipped(tmp_path, monkeypatch):
    from carbody.library import build_library, load_library

    reference = build_library()
    cache = tmp_path / "cache"
    monkeypatch.setenv("CARBODY_CACHE_DIR", str(cache))
    load_library()
    (cached,) = cache.iterdir()
    whole = cached.read_bytes()
    assert len(whole) > 1000
    for damage in (b"not an archive", whole[: len(whole) // 2], b""):
        cached.write_bytes(damage)
        assert np.array_equal(load_library().S, reference.S)
        with np.load(cached) as again:  # written again, whole
            assert np.array_equal(again["S"], reference.S)
    blocked = tmp_path / "a file"
    blocked.write_text("")
    monkeypatch.setenv("CARBODY_CACHE_DIR", str(blocked / "cache"))
    assert np.array_equal(load_library().S, reference.S)
    monkeypatch.setenv("CARBODY_CACHE_DIR", str(cache))
    cached.unlink()
    cached.mkdir()  # a folder where the cache goes: read past, and not written
    assert np.array_equal(load_library().S, reference.S)
    assert not [p for p in tmp_path.rglob("*.tmp*")]


@pytest.mark.parametrize("change, says", [
    (lambda m: {**m, "nose_centre": [99999, 5]}, "lies outside the 1000 x 640 image"),  # a typo's mark
    (lambda m: dict(list(m.items())[:4]), "at least 5"),
    (lambda m: {k: [300, 300] for k in list(m)[:8]}, "coincident"),
    (lambda m: {**m, "bogus": [10, 10]}, "unknown keypoint name 'bogus'"),
])
def test_marks_the_fit_cannot_use_are_refused_before_the_classifier(capsys, tmp_path, change, says):
    """Checked with the photo, before any stage: a mark far off the photo once sent the classifier
    to crop a square of 70 GB round it (an OpenCV traceback), without a view told."""
    import carbody

    marks = change(dict(MARKS["keypoints"]))
    stages = []
    with pytest.raises(CarbodyError, match=says):
        carbody.reconstruct(PHOTO, marks, on_stage=stages.append)
    assert stages == []
    path = tmp_path / "k.json"
    path.write_text(json.dumps({**MARKS, "keypoints": marks}))
    assert says in refused(capsys, "reconstruct", PHOTO, "-k", path, "-o", tmp_path / "out")
    assert not (tmp_path / "out").exists()
    if "outside" in says:  # `carbody view -k` crops to the marks too
        assert says in refused(capsys, "view", PHOTO, "-k", path)


def test_a_box_far_larger_than_the_picture_is_refused(capsys):
    assert "more than 3 times the 1000x640 px picture" in refused(capsys, "view", PHOTO, "--box", 0, 0, 99999, 5)


@pytest.mark.parametrize("arguments", [
    dict(wheelbase_mm="long"), dict(wheelbase_mm=[2700]), dict(elevation_deg="5"), dict(elevation_deg=None),
    dict(camera_distance_mm=[7000]), dict(camera_distance_mm=-1), dict(principal_point=("a", "b")),
    dict(focal_35mm="26"), dict(name=["car"]), dict(library="the shipped one"), dict(reject_outliers="no"),
    dict(view_prior_weight="1"), dict(view=[30]), dict(view=object()), dict(view=True), dict(view="front 999"),
    dict(elevation_deg=100), dict(view=None, elevation_deg=100), dict(outline="yes"), dict(wheels="no"),
])
def test_the_api_raises_a_carbody_error_for_each_bad_argument(arguments):
    import carbody

    stages = []
    kwargs = {"view": 30, **arguments, "on_stage": stages.append}
    with pytest.raises(CarbodyError):
        carbody.reconstruct(PHOTO, KEYPOINTS, **kwargs)
    assert stages == []  # refused before the classifier, the fit and the surfaces


@pytest.mark.parametrize("image, keypoints", [
    (5, KEYPOINTS), (None, KEYPOINTS), (np.zeros((3, 3, 3, 3)), KEYPOINTS), (PHOTO, 5),
    (PHOTO, list(MARKS["keypoints"].items())), (PHOTO, {1: (2, 3)}), (PHOTO, {"nose_centre": ("283", "310")}),
    (PHOTO, {"nose_centre": (True, 3)}), (PHOTO, b"car.json"),
])
def test_the_api_raises_a_carbody_error_for_each_bad_photo_or_mark(image, keypoints):
    import carbody

    with pytest.raises(CarbodyError):
        carbody.reconstruct(image, keypoints, view=30)


@pytest.mark.parametrize("arguments", [
    dict(image_size="1000x640"), dict(image_size=(1000, 640, 3)), dict(library="x"), dict(options="x"),
    dict(prior_weight="a"), dict(view_prior_weight=[1]), dict(focal_px="900"),
])
def test_fit_wireframe_raises_a_carbody_error_for_each_bad_argument(arguments):
    from carbody.fit import fit_wireframe

    with pytest.raises(CarbodyError):
        fit_wireframe(MARKS["keypoints"], **{"view": 30, "image_size": (1000, 640), **arguments})


def test_a_template_manifest_with_a_byte_order_mark_is_read_and_a_misshapen_one_refused(capsys, template_copy):
    from carbody.templates import load_manifest

    manifest = template_copy / "manifest.json"
    rows = load_manifest(template_copy)
    manifest.write_bytes(b"\xef\xbb\xbf" + manifest.read_bytes())
    assert load_manifest(template_copy) == rows
    manifest.write_text(json.dumps({"cars": rows}))
    assert "not a template manifest" in refused(capsys, "templates", "list", "--dir", template_copy)
    manifest.write_text(json.dumps([{**rows[0], "file": ["a.step"]}]))
    assert "not a template manifest" in refused(capsys, "library", "--dir", template_copy, "--no-cache")
