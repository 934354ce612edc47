"""Keypoint annotations in: the project's JSON, COCO keypoints and labelme, any subset of names.

A keypoint on the car's right half is named by its left twin's mirror name (``<name>_right``);
a keypoint on the symmetry plane has one name. Every reader returns an :class:`Annotation` and
:func:`check_keypoints` refuses what the fit cannot use, one line per problem.
"""
from __future__ import annotations

import difflib
import json
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


def _pair(value, where: str) -> tuple[float, float]:
    try:
        u, v = (float(c) for c in value[:2])
    except (TypeError, ValueError, IndexError):
        raise KeypointError(f"{where}: expected [u, v], got {value!r}") from None
    return u, v


def _project_json(data: dict, where: str) -> Annotation:
    kps = data["keypoints"]
    if not isinstance(kps, dict):
        raise KeypointError(f"{where}: 'keypoints' must map names to [u, v]")
    points = {str(n): _pair(p, f"{where}: keypoint {n!r}") for n, p in kps.items() if p is not None}
    size = data.get("image_size") or (
        (data["width"], data["height"]) if "width" in data and "height" in data else None)
    return Annotation(points, data.get("image"), tuple(int(s) for s in size) if size else None)


def _coco_json(data: dict, where: str, annotation: int) -> Annotation:
    cats = {c.get("id"): c for c in data.get("categories", [])}
    anns = data.get("annotations") or []
    if not anns:
        raise KeypointError(f"{where}: COCO file has no annotations")
    if not 0 <= annotation < len(anns):
        raise KeypointError(f"{where}: no annotation #{annotation} (file has {len(anns)})")
    ann = anns[annotation]
    cat = cats.get(ann.get("category_id")) or (next(iter(cats.values())) if len(cats) == 1 else None)
    if cat is None or "keypoints" not in cat:
        raise KeypointError(f"{where}: COCO annotation's category lists no keypoint names")
    names, flat = cat["keypoints"], ann.get("keypoints") or []
    if len(flat) != 3 * len(names):
        raise KeypointError(f"{where}: COCO annotation has {len(flat)} numbers for {len(names)} "
                            f"keypoint names (expected {3 * len(names)})")
    points = {}
    for i, name in enumerate(names):
        u, v, flag = flat[3 * i:3 * i + 3]
        if flag:  # COCO: 0 = not labelled
            points[str(name)] = _pair((u, v), f"{where}: keypoint {name!r}")
    image, size = None, None
    for img in data.get("images", []):
        if img.get("id") == ann.get("image_id"):
            image = img.get("file_name")
            if "width" in img and "height" in img:
                size = (int(img["width"]), int(img["height"]))
    return Annotation(points, image, size)


def _labelme_json(data: dict, where: str) -> Annotation:
    points = {}
    for shape in data["shapes"]:
        if shape.get("shape_type", "point") != "point":
            continue
        name = str(shape.get("label", ""))
        if name in points:
            raise KeypointError(f"{where}: keypoint {name!r} is marked twice")
        pts = shape.get("points") or []
        if len(pts) != 1:
            raise KeypointError(f"{where}: point {name!r} has {len(pts)} coordinates, expected 1")
        points[name] = _pair(pts[0], f"{where}: keypoint {name!r}")
    size = (int(data["imageWidth"]), int(data["imageHeight"])) \
        if data.get("imageWidth") and data.get("imageHeight") else None
    return Annotation(points, data.get("imagePath"), size)


def read_keypoints(path: str | Path, annotation: int = 0) -> Annotation:
    """Read a keypoint file in any of the three formats (detected from its structure).

    Args:
        path: JSON file: ``{"image", "keypoints": {name: [u, v]}}``, COCO keypoints
            (``categories[].keypoints`` + ``annotations[].keypoints`` as u, v, flag triples), or
            labelme (``shapes`` of ``shape_type`` point).
        annotation: which annotation of a COCO file (default the first).
    Raises:
        KeypointError: unreadable, not JSON, a name given twice in one object, or none of the
            three structures.
    """
    path = Path(path)

    def unique(pairs: list) -> dict:  # JSON keeps the last of a name given twice: say so instead
        names = [k for k, _ in pairs]
        twice = next((k for k in names if names.count(k) > 1), None)
        if twice is not None:
            raise KeypointError(f"{path}: {twice!r} is given twice in one object (which is meant?)")
        return dict(pairs)

    try:
        data = json.loads(path.read_text(), object_pairs_hook=unique)
    except OSError as exc:
        raise KeypointError(f"{path}: cannot read keypoint file ({exc.strerror or exc})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise KeypointError(f"{path}: keypoint file is not JSON ({exc})") from None
    where = str(path)
    if isinstance(data, dict) and "keypoints" in data and isinstance(data["keypoints"], dict):
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
    if not hasattr(points, "items"):
        raise KeypointError(f"keypoints must map names to (u, v) pixels, got a {type(points).__name__}")
    chosen, uv = [], []
    for name, p in points.items():
        if name not in slots:
            close = difflib.get_close_matches(name, list(slots), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else \
                f" (names are the 35 keypoints of the topology, right-half ones end in {RIGHT_SUFFIX!r})"
            raise KeypointError(f"unknown keypoint name {name!r}{hint}")
        try:
            u, v = (float(c) for c in p)
        except (TypeError, ValueError):
            raise KeypointError(f"keypoint {name!r}: expected (u, v) pixels, got {p!r}") from None
        if not (np.isfinite(u) and np.isfinite(v)):
            raise KeypointError(f"keypoint {name!r} has a NaN or infinite coordinate ({u}, {v})")
        if image_size is not None:
            w, h = image_size
            if not (0 <= u <= w and 0 <= v <= h):
                raise KeypointError(f"keypoint {name!r} at ({u:g}, {v:g}) lies outside the "
                                    f"{w} x {h} image")
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
