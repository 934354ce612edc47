"""Keypoint files (project JSON, COCO, labelme), mirror names, checks, visibility from geometry."""
import json

import pytest

from carbody.errors import KeypointError
from carbody.camera import View
from carbody.fit.keypoints_io import check_keypoints, keypoint_slots, read_keypoints
from carbody.fit.visibility import visible_keypoints

PTS = {"nose_centre": [100.0, 200.0], "front_top_corner_right": [150.0, 190.0],
       "a_pillar_base": [300.0, 150.0], "rear_arch_top": [700.0, 260.0], "sill_rear": [650.0, 330.0]}


def test_every_keypoint_and_its_mirror_has_a_slot(topology):
    slots = keypoint_slots(topology)
    off_plane = [k for k in topology.keypoints if not k.on_symmetry_plane]
    assert len(slots) == 35 + len(off_plane)
    right = slots["front_top_corner_right"]
    assert right.is_mirror and right.point_index == slots["front_top_corner"].point_index
    assert "nose_centre_right" not in slots


def test_project_json(tmp_path):
    p = tmp_path / "k.json"
    p.write_text(json.dumps({"image": "car.jpg", "keypoints": PTS}))
    ann = read_keypoints(p)
    assert ann.image == "car.jpg" and ann.points["front_top_corner_right"] == (150.0, 190.0)


def test_coco(tmp_path):
    names = list(PTS) + ["tail_top_centre"]
    flat = [c for n in PTS for c in (*PTS[n], 2)] + [0, 0, 0]
    data = {"images": [{"id": 7, "file_name": "car.jpg", "width": 800, "height": 400}],
            "categories": [{"id": 1, "name": "car", "keypoints": names}],
            "annotations": [{"image_id": 7, "category_id": 1, "keypoints": flat}]}
    p = tmp_path / "coco.json"
    p.write_text(json.dumps(data))
    ann = read_keypoints(p)
    assert set(ann.points) == set(PTS) and ann.image_size == (800, 400) and ann.image == "car.jpg"


def test_labelme(tmp_path):
    data = {"imagePath": "car.jpg", "imageWidth": 800, "imageHeight": 400,
            "shapes": [{"label": n, "points": [p], "shape_type": "point"} for n, p in PTS.items()]
            + [{"label": "glass", "points": [[0, 0], [1, 1], [2, 0]], "shape_type": "polygon"}]}
    p = tmp_path / "lm.json"
    p.write_text(json.dumps(data))
    ann = read_keypoints(p)
    assert ann.points == {n: tuple(p) for n, p in PTS.items()} and ann.image_size == (800, 400)


def test_unreadable_keypoint_files(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(KeypointError, match="not JSON"):
        read_keypoints(bad)
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"hello": 1}))
    with pytest.raises(KeypointError, match="not a keypoint file"):
        read_keypoints(other)
    with pytest.raises(KeypointError, match="no such keypoint file"):
        read_keypoints(tmp_path / "missing.json")


def test_checks_accept_a_good_set():
    slots, uv = check_keypoints({n: tuple(p) for n, p in PTS.items()}, (800, 400))
    assert [s.name for s in slots] == list(PTS) and uv.shape == (5, 2)


@pytest.mark.parametrize("points,match", [
    ({**PTS, "nose_centr": [1, 1]}, "unknown keypoint name 'nose_centr'.*nose_centre"),
    ({**PTS, "nose_centre": [float("nan"), 3]}, "NaN"),
    ({**PTS, "nose_centre": [900, 3]}, "outside"),
    (dict(list(PTS.items())[:4]), "at least"),
    ({n: [100 + i, 100 + 2 * i] for i, n in enumerate(PTS)}, "one line"),
    ({n: [100, 100] for n in PTS}, "coincident"),
    ({**PTS, "sill_front": [300, 300], "sill_front_right": [301.5, 300.5]}, "'sill_front' and 'sill_front_right' are "
     "marked on one spot"),
    ({**PTS, "nose_centre": [3, 4, 5]}, "expected \\[u, v\\] pixels"),
    (list(PTS.items()), "must map names to"),
])
def test_checks_refuse_bad_keypoints(points, match):
    with pytest.raises(KeypointError, match=match):
        check_keypoints(points, (800, 400))


def test_side_view_sees_the_left_side_only():
    seen = set(visible_keypoints(View(90)))
    assert not any(n.endswith("_right") for n in seen)
    for n in ("front_arch_top", "rear_arch_top", "window_front_top", "b_pillar_sill", "roof_rear_corner"):
        assert n in seen


def test_front_view_sees_both_front_corners_and_no_tail():
    seen = set(visible_keypoints(View(0)))
    assert {"front_top_corner", "front_top_corner_right", "nose_centre"} <= seen
    assert not seen & {"rear_bumper_bottom_centre", "tail_top_centre", "rear_arch_rear", "rear_bottom_corner"}


def test_three_quarter_views_see_a_paper_sized_set():
    front, rear = visible_keypoints(View(30)), visible_keypoints(View(150))
    # The paper annotates 17 (front 30°) and 19 (rear 30°); geometry allows a few more.
    assert 17 <= len(front) <= 45 and 19 <= len(rear) <= 45
    assert "tail_top_centre" not in front and "nose_centre" not in rear
    # Mirror symmetry: the other side's view sees the same points under their mirror names.
    right = visible_keypoints(View(330))
    assert sorted(_swap(n) for n in right) == sorted(front)


def test_a_close_camera_sees_less_of_the_faces_turned_away():
    """From 1.5 wheelbases (≈ 4 m) at front 60° the far front corner lies behind the nose's face,
    which an orthographic camera at 60° still sees; from far away the two agree."""
    from carbody.camera import AngleError
    from carbody.fit.solve import car_centre
    from carbody.library import load_library

    mean = load_library().S.mean(axis=1)
    ortho = set(visible_keypoints(View(60)))
    close = set(visible_keypoints(View(60, 0, 0, 1500.0, car_centre(mean))))
    far = set(visible_keypoints(View(60, 0, 0, 1e6, car_centre(mean))))
    assert "front_top_corner_right" in ortho - close
    assert close < ortho and far == ortho
    with pytest.raises(AngleError, match="inside the car"):
        visible_keypoints(View(60, 0, 0, 100.0, car_centre(mean)))


def test_the_marks_names_say_which_views_can_see_them(library):
    """The view search's facing table (the library's mean car, the policy's margin): every
    template's keypoints visible at views 30° apart (level and from 10° up) all face the view
    they were seen from; from the mirror of a side view, or the other end of a front or rear
    three-quarter view, a good part of them cannot be seen."""
    import numpy as np

    from carbody.fit.visibility import FacingTable
    from carbody.policy import FIT_POLICY

    table = FacingTable(library.S.mean(axis=1).reshape(-1, 3))
    margin = FIT_POLICY.visibility_margin_deg
    row = {n: i for i, n in enumerate(table.names)}

    def hidden(names, azimuth, elevation) -> float:
        facing = table.facing(azimuth % 360, elevation, margin)[:, 0]
        return np.mean([not facing[row[n]] for n in names])

    for t in range(len(library.template_names)):
        cp = library.points(library.original(t))
        for elevation in (0, 10):
            for azimuth in range(0, 360, 30):
                names = visible_keypoints(View(azimuth, elevation), cp)
                assert hidden(names, azimuth, elevation) == 0
                if 30 <= azimuth % 180 <= 150:
                    assert hidden(names, 360 - azimuth, elevation) > FIT_POLICY.max_rejected_fraction
                if min(azimuth % 180, 180 - azimuth % 180) <= 30 and azimuth % 90:
                    assert hidden(names, 180 - azimuth, elevation) > 0


def _swap(name):
    from carbody.topology import load_topology

    off_plane = {k.name for k in load_topology().keypoints if not k.on_symmetry_plane}
    if name.endswith("_right"):
        return name.removesuffix("_right")
    return name + "_right" if name in off_plane else name


def test_focal_length_from_35mm_equivalent_or_exif(tmp_path):
    """A phone photo's EXIF gives the focal length unless the photo was cropped since."""
    from PIL import Image

    from carbody.errors import FitError
    from carbody.fit.focal import FILM_DIAGONAL_MM, focal_length_px

    def photo(name, size, exif_size, orientation=1):
        exif = Image.Exif()
        exif[0x0112] = orientation
        ifd = exif.get_ifd(0x8769)
        ifd[0xA405], ifd[0xA002], ifd[0xA003] = 26, *exif_size
        Image.new("RGB", size).save(tmp_path / name, exif=exif)
        return tmp_path / name

    f, source = focal_length_px(photo("a.jpg", (400, 300), (400, 300)), (400, 300), None)
    assert f == pytest.approx(26 * 500 / FILM_DIAGONAL_MM) and "EXIF" in source
    assert focal_length_px(photo("b.jpg", (400, 300), (800, 600)), (400, 300), None) == (None, "")
    # stored on its side (EXIF orientation 6), read upright: 300 x 400
    f, source = focal_length_px(photo("c.jpg", (400, 300), (400, 300), 6), (300, 400), None)
    assert f == pytest.approx(26 * 500 / FILM_DIAGONAL_MM) and "EXIF" in source
    assert focal_length_px(tmp_path / "missing.png", (400, 300), 50.0)[0] == pytest.approx(50 * 500 / FILM_DIAGONAL_MM)
    with pytest.raises(FitError, match="focal length"):
        focal_length_px(tmp_path / "missing.png", (400, 300), -1.0)
