"""Keypoint annotations in: the project's JSON, COCO keypoints and labelme, any subset of names.

A keypoint on the car's right half is named by its left twin's mirror name (``<name>_right``);
a keypoint on the symmetry plane has one name. Every reader returns an :class:`Annotation` and
:func:`check_keypoints` refuses what the fit cannot use, one line per problem.
"""
from __future__ import annotations

import difflib
import json
import numbers
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from carbody.errors import KeypointError
from carbody.topology import Topology, load_topology
from carbody.wireframe import MIRROR, RIGHT_SUFFIX

#: Fewest keypoints a fit accepts: image scale and offset (3), the view (3) and at least a few
#: shape equations need 2k >= 10 coordinates.
MIN_KEYPOINTS = 5

#: Keypoints whose centred spread (RMS, px) is below this are "coincident".
MIN_SPREAD_PX = 2.0

#: Keypoints whose second principal spread is below this fraction of the first are "collinear".
MIN_ASPECT = 0.01

#: A left/right pair of marks closer than this fraction of the marks' RMS spread (≈ 3 px for a
#: car 900 px wide) is one point marked under both names: the twins lie a car's width apart, and
#: seen edge-on, where they would meet in the photo, the far one is hidden by the car.
MIN_TWIN_SEPARATION = 0.01


@dataclass(frozen=True)
class KeypointSlot:
    """One markable point of the whole car: a left-half keypoint or its right-half mirror.

    Attributes:
        name: the name used in annotations.
        point_index: row of the (280, 3) control-point array of the left half.
        sign: (3,) float, (1, 1, 1) for the left half, (-1, 1, 1) for the mirror.
        keypoint_id: the paper's Fig. 6 number (same for both twins).
    """

    name: str
    point_index: int
    sign: np.ndarray = field(compare=False)
    keypoint_id: int = 0

    @property
    def is_mirror(self) -> bool:
        return bool(self.sign[0] < 0)


def keypoint_slots(topology: Topology | None = None) -> dict[str, KeypointSlot]:
    """Every name an annotation may use, left keypoints first then right mirrors, in id order."""
    topo = topology or load_topology()
    slots: dict[str, KeypointSlot] = {}
    idx = topo.keypoint_point_indices
    for k, i in zip(topo.keypoints, idx):
        slots[k.name] = KeypointSlot(k.name, int(i), np.ones(3), k.id)
    for k, i in zip(topo.keypoints, idx):
        if k.mirror_name:
            slots[k.mirror_name] = KeypointSlot(k.mirror_name, int(i), MIRROR.copy(), k.id)
    return slots


@dataclass
class Annotation:
    """Keypoints marked on one image.

    Attributes:
        points: {name: (u, v)} pixels, u right, v down.
        image: the image file the annotation names (may be relative to the annotation), or None.
        image_size: (width, height) pixels when the file states it, else None.
    """

    points: dict[str, tuple[float, float]]
    image: str | None = None
    image_size: tuple[int, int] | None = None


def _number(value, where: str) -> float:
    """A JSON or Python number (a string or a boolean is none: ``"28"`` is no pixel)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise KeypointError(f"{where}: expected a number, got {_shown(value)}")
    return float(value)


def _pair(value, where: str) -> tuple[float, float]:
    """(u, v) pixels from two numbers (a list, a tuple or a (2,) array)."""
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__") or len(value) != 2:
        raise KeypointError(f"{where}: expected [u, v] pixels, got {_shown(value)}")
    try:
        u, v = (_number(c, where) for c in value)
    except KeypointError:
        raise KeypointError(f"{where}: expected [u, v] pixels as two numbers, got {_shown(value)}") from None
    return u, v


def _shown(value, limit: int = 60) -> str:
    """``value`` as a message shows it: short (a hostile file's value may be megabytes)."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + "…"


def _image_size(value, where: str) -> tuple[int, int]:
    """(width, height) pixels from two positive whole numbers."""
    try:
        w, h = _pair(value, where)
    except KeypointError:
        raise KeypointError(f"{where}: expected [width, height] pixels, got {_shown(value)}") from None
    if not all(np.isfinite(s) and s >= 1 and s == int(s) for s in (w, h)):
        raise KeypointError(f"{where}: [width, height] must be whole numbers of pixels, got {_shown(value)}")
    return int(w), int(h)


def _text(data: dict, key: str, where: str) -> str | None:
    """An optional string field (a file name)."""
    value = data.get(key)
    if value is not None and not isinstance(value, str):
        raise KeypointError(f"{where}: {key!r} must be a file name, got {_shown(value)}")
    return value


def _field(data: dict, key: str, kind: type, where: str, what: str):
    """A required field of JSON type ``kind`` (list or dict), named in the message when it is not."""
    value = data.get(key)
    if not isinstance(value, kind):
        raise KeypointError(f"{where}: {key!r} must be {what}, got {_shown(value)}")
    return value


def _project_json(data: dict, where: str) -> Annotation:
    kps = data["keypoints"]
    points = {n: _pair(p, f"{where}: keypoint {n!r}") for n, p in kps.items() if p is not None}
    if data.get("image_size") is not None:
        size = _image_size(data["image_size"], f"{where}: 'image_size'")
    elif data.get("width") is not None or data.get("height") is not None:
        size = _image_size((data["width"], data["height"]), f"{where}: 'width' and 'height'")
    else:
        size = None
    return Annotation(points, _text(data, "image", where), size)


def _coco_json(data: dict, where: str, annotation: int) -> Annotation:
    categories = _field(data, "categories", list, where, "a list of categories")
    anns = _field(data, "annotations", list, where, "a list of annotations")
    images = data.get("images", [])
    if not isinstance(images, list):
        raise KeypointError(f"{where}: 'images' must be a list of images, got {_shown(images)}")
    for key, items in (("categories", categories), ("annotations", anns), ("images", images)):
        bad = next((x for x in items if not isinstance(x, dict)), None)
        if bad is not None:
            raise KeypointError(f"{where}: every one of {key!r} must be an object, got {_shown(bad)}")
    if not anns:
        raise KeypointError(f"{where}: COCO file has no annotations")
    if isinstance(annotation, bool) or not isinstance(annotation, int) or not 0 <= annotation < len(anns):
        raise KeypointError(f"{where}: no annotation #{annotation} (file has {len(anns)})")
    ann = anns[annotation]

    def key(value):  # an id as a dictionary key (a list or an object is no id)
        return value if isinstance(value, (int, str)) or value is None else repr(value)

    cats = {key(c.get("id")): c for c in categories}
    cat = cats.get(key(ann.get("category_id"))) or (next(iter(cats.values())) if len(cats) == 1 else None)
    if cat is None or "keypoints" not in cat:
        raise KeypointError(f"{where}: COCO annotation's category lists no keypoint names")
    names = _field(cat, "keypoints", list, where, "the category's list of keypoint names")
    bad = next((n for n in names if not isinstance(n, str)), None)
    if bad is not None:
        raise KeypointError(f"{where}: COCO keypoint names must be strings, got {_shown(bad)}")
    flat = ann.get("keypoints") or []
    if not isinstance(flat, list):
        raise KeypointError(f"{where}: the annotation's 'keypoints' must be a list of u, v, flag numbers, "
                            f"got {_shown(flat)}")
    if len(flat) != 3 * len(names):
        raise KeypointError(f"{where}: COCO annotation has {len(flat)} numbers for {len(names)} "
                            f"keypoint names (expected {3 * len(names)})")
    points = {}
    for i, name in enumerate(names):
        u, v, flag = flat[3 * i:3 * i + 3]
        if _number(flag, f"{where}: keypoint {name!r}'s visibility flag"):  # COCO: 0 = not labelled
            if name in points:
                raise KeypointError(f"{where}: keypoint {name!r} is named twice in the category")
            points[name] = _pair((u, v), f"{where}: keypoint {name!r}")
    image, size = None, None
    for img in images:
        if key(img.get("id")) == key(ann.get("image_id")):
            image = _text(img, "file_name", where)
            if "width" in img and "height" in img:
                size = _image_size((img["width"], img["height"]), f"{where}: the image's 'width' and 'height'")
    return Annotation(points, image, size)


def _labelme_json(data: dict, where: str) -> Annotation:
    points = {}
    for shape in data["shapes"]:
        if not isinstance(shape, dict):
            raise KeypointError(f"{where}: every one of 'shapes' must be an object, got {_shown(shape)}")
        if shape.get("shape_type", "point") != "point":
            continue
        name = shape.get("label", "")
        if not isinstance(name, str):
            raise KeypointError(f"{where}: a point's 'label' must be a keypoint name, got {_shown(name)}")
        if name in points:
            raise KeypointError(f"{where}: keypoint {name!r} is marked twice")
        pts = shape.get("points") or []
        if not isinstance(pts, list) or len(pts) != 1:
            raise KeypointError(f"{where}: point {name!r} must hold one [u, v], got {_shown(pts)}")
        points[name] = _pair(pts[0], f"{where}: keypoint {name!r}")
    size = None
    if data.get("imageWidth") is not None or data.get("imageHeight") is not None:
        size = _image_size((data.get("imageWidth"), data.get("imageHeight")),
                           f"{where}: 'imageWidth' and 'imageHeight'")
    return Annotation(points, _text(data, "imagePath", where), size)


def read_keypoints(path: str | Path, annotation: int = 0) -> Annotation:
    """Read a keypoint file in any of the three formats (detected from its structure).

    Args:
        path: JSON file (UTF-8, a byte-order mark allowed, at most
            :data:`~carbody.inputs.MAX_JSON_BYTES`): ``{"image", "image_size", "keypoints":
            {name: [u, v]}}``, COCO keypoints (``categories[].keypoints`` +
            ``annotations[].keypoints`` as u, v, flag triples), or labelme (``shapes`` of
            ``shape_type`` point).
        annotation: which annotation of a COCO file (default the first).
    Raises:
        KeypointError: missing, a folder, not a regular file, too large, not JSON, a name given
            twice in one object, none of the three structures, or a field of the wrong type
            (a coordinate that is not a number, an image size that is not two whole numbers).
    """
    from carbody.inputs import read_json

    where = str(path)
    data = read_json(path, "keypoint file", KeypointError)
    if isinstance(data, dict) and isinstance(data.get("keypoints"), dict):
        return _project_json(data, where)
    if isinstance(data, dict) and "annotations" in data and "categories" in data:
        return _coco_json(data, where, annotation)
    if isinstance(data, dict) and isinstance(data.get("shapes"), list):
        return _labelme_json(data, where)
    raise KeypointError(f"{where}: not a keypoint file (expected the project's JSON, COCO keypoints "
                        "or labelme)")


def check_keypoints(points: dict[str, tuple[float, float]],
                    image_size: tuple[int, int] | None = None,
                    topology: Topology | None = None,
                    min_keypoints: int = MIN_KEYPOINTS) -> tuple[list[KeypointSlot], np.ndarray]:
    """Refuse keypoints the fit cannot use; return their slots and pixel coordinates.

    Args:
        points: {name: (u, v)} pixels.
        image_size: (width, height) px; when given, every point must lie on the image.
    Returns:
        (slots in the order of ``points``, (k, 2) float pixel coordinates).
    Raises:
        KeypointError: an unknown name, NaN or infinite or off-image coordinates, fewer than
            ``min_keypoints`` points, points that are coincident or all on one line, or a
            left/right pair marked on one spot (``MIN_TWIN_SEPARATION``).
    """
    slots = keypoint_slots(topology)
    if image_size is not None:
        image_size = _image_size(image_size, "image_size")
    if not hasattr(points, "items"):
        raise KeypointError(f"keypoints must map names to (u, v) pixels, got a {type(points).__name__}")
    chosen, uv = [], []
    for name, p in points.items():
        if not isinstance(name, str):
            raise KeypointError(f"keypoint names must be strings, got {_shown(name)}")
        if name not in slots:
            close = difflib.get_close_matches(name, list(slots), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else \
                f" (names are the 35 keypoints of the topology, right-half ones end in {RIGHT_SUFFIX!r})"
            raise KeypointError(f"unknown keypoint name {_shown(name)}{hint}")
        u, v = _pair(p, f"keypoint {name!r}")
        if not (np.isfinite(u) and np.isfinite(v)):
            raise KeypointError(f"keypoint {name!r} has a NaN or infinite coordinate ({u}, {v})")
        if image_size is not None:
            _on_image(name, u, v, image_size)
        chosen.append(slots[name])
        uv.append((u, v))
    if len(chosen) < min_keypoints:
        raise KeypointError(f"{len(chosen)} keypoint(s) given; the fit needs at least {min_keypoints}")
    uv = np.array(uv, dtype=float)
    spread = np.linalg.svd(uv - uv.mean(axis=0), compute_uv=False) / np.sqrt(len(uv))
    if spread[0] < MIN_SPREAD_PX:
        raise KeypointError(f"the keypoints are coincident (spread {spread[0]:.3g} px)")
    if spread[1] < MIN_ASPECT * spread[0]:
        raise KeypointError("the keypoints all lie on one line: the fit cannot recover a 3D shape")
    _check_twins(chosen, uv)
    return chosen, uv


def check_on_image(points: dict[str, tuple[float, float]], image_size: tuple[int, int]) -> None:
    """Refuse a mark that is not two numbers or lies off the image (``image_size``: width, height
    px); a mark at NaN is left to :func:`check_keypoints`.

    Raises:
        KeypointError: naming the first such mark.
    """
    for name, p in points.items():
        u, v = _pair(p, f"keypoint {name!r}")
        if np.isfinite(u) and np.isfinite(v):
            _on_image(name, u, v, image_size)


def _on_image(name: str, u: float, v: float, image_size: tuple[int, int]) -> None:
    w, h = image_size
    if not (0 <= u <= w and 0 <= v <= h):
        raise KeypointError(f"keypoint {name!r} at ({u:g}, {v:g}) lies outside the {w} x {h} image")


def _check_twins(slots: list[KeypointSlot], uv: np.ndarray) -> None:
    """Refuse a left/right pair marked on one spot (``MIN_TWIN_SEPARATION``)."""
    at = {s.name: p for s, p in zip(slots, uv)}
    limit = MIN_TWIN_SEPARATION * float(np.sqrt(np.mean(np.sum((uv - uv.mean(axis=0)) ** 2, axis=1))))
    for name, p in at.items():
        twin = at.get(name + RIGHT_SUFFIX)
        if twin is not None and np.linalg.norm(p - twin) < limit:
            raise KeypointError(f"{name!r} and {name + RIGHT_SUFFIX!r} are marked on one spot "
                                f"({np.linalg.norm(p - twin):.1f} px apart): the car's left and right twins "
                                "lie its width apart; keep the one the photo shows")


def check_image_size(annotation: Annotation, size: tuple[int, int]) -> None:
    """Refuse an annotation whose file states another image size than the photo's (marks made on
    a resized copy land in the wrong place).

    Raises:
        KeypointError: naming both sizes.
    """
    if annotation.image_size is not None and tuple(int(s) for s in annotation.image_size) != tuple(size):
        (aw, ah), (w, h) = annotation.image_size, size
        raise KeypointError(f"the keypoints were marked on a {aw} x {ah} image but the photo is {w} x {h}")


def write_keypoints(path: str | Path, points: dict[str, tuple[float, float]],
                    image: str | None = None, image_size: tuple[int, int] | None = None) -> Path:
    """Write the project's keypoint JSON (``{"image", "image_size", "keypoints"}``)."""
    path = Path(path)
    data: dict = {"image": image, "keypoints": {n: [float(u), float(v)] for n, (u, v) in points.items()}}
    if image_size:
        data["image_size"] = list(image_size)
    path.write_text(json.dumps(data, indent=1))
    return path
