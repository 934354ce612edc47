"""The near end's look: which way a car seen three-quarter on faces (issue 26).

On real photos the classifier reads a three-quarter view's axis well but often takes the car's
front for its rear: it reads the body's whole layout, and real layouts fool it (a cab-forward
supercar, a pickup's bed, a close wide-angle shot). So it takes a second look at the car's box
with only the near end left: the box from the end nearer the camera to :data:`END_KEEP` of its
width, everything beyond painted grey (:func:`end_look`). Both looks say which way the car
faces (:func:`combine_looks`); the angle comes from the whole car. The network learns both looks: ``carbody end-looks`` writes the end
looks of a set of framed renders (:func:`write_end_looks`), trained on beside the renders
themselves.

Which end is near follows from the view: in the view classes' frame (0° the front, 90° the
car's left side toward the camera), a view θ with θ mod 180° below 90° shows its near end on
the picture's left (front-left and rear-right views), else on its right.
"""
from __future__ import annotations

import csv
import functools
import json
import shutil
from pathlib import Path

import numpy as np

from carbody.errors import ViewError
from carbody.view.labels import CLASS_ANGLES_DEG, angular_difference, continuous_estimate

#: A view is three-quarter when its axis lies at least this far from end-on and from side-on:
#: nearer an end the whole car is its end already; nearer the side both ends show alike.
THREE_QUARTER_MARGIN_DEG = 20.0

#: The near end's look keeps this share of the box's width from its near side.
END_KEEP = 0.5

#: Training draws the share kept from this range (a car's near end is wider or narrower in its
#: box as the view turns).
END_KEEP_RANGE = (0.4, 0.6)

#: The grey that covers the rest (the picture's middle grey: the network's input mean).
END_GREY = 128

#: The ``dataset.json`` key that marks a set of end looks, and the weights' metadata key that
#: says the network was trained on them.
END_LOOK_KEY = "end_look"


def is_three_quarter(view_deg: float, margin_deg: float = THREE_QUARTER_MARGIN_DEG) -> bool:
    """Whether the view (degrees) lies at least ``margin_deg`` from end-on and from side-on."""
    axis = float(view_deg) % 180.0
    return min(axis, 180.0 - axis) >= margin_deg and abs(axis - 90.0) >= margin_deg


def second_look_view(box, probs: np.ndarray) -> float | None:
    """The view (degrees) a picture's second look is taken at: the first look's, read from its
    class probabilities ``probs``, when the picture has a ``box`` and that view is three-quarter
    on; else None (no second look)."""
    if box is None:
        return None
    view = continuous_estimate(probs)
    return view if is_three_quarter(view) else None


def near_end_on_left(view_deg: float) -> bool:
    """Whether the end nearer the camera lies on the picture's left (module docstring)."""
    return float(view_deg) % 180.0 < 90.0


def end_look(image: np.ndarray, box, view_deg: float, keep: float = END_KEEP) -> np.ndarray:
    """(h, w, 3) uint8: ``image`` with everything beyond ``keep`` of the car's ``box`` (x0, y0,
    x1, y1) pixels, counted from its near end at ``view_deg``, painted :data:`END_GREY` (a copy;
    the whole height: what lies past the car's far end is no evidence of its near end)."""
    x0, _, x1, _ = (float(v) for v in box)
    out = np.array(image, dtype=np.uint8, copy=True)
    w = out.shape[1]
    if near_end_on_left(view_deg):
        cut = int(round(x0 + keep * (x1 - x0)))
        out[:, min(max(cut, 0), w):] = END_GREY
    else:
        cut = int(round(x1 - keep * (x1 - x0)))
        out[:, :min(max(cut, 0), w)] = END_GREY
    return out


@functools.cache
def facing_halves() -> np.ndarray:
    """(24, 24) float: row k weighs each class by whether it faces class k's way, 1 within 90°
    of it, 0.5 at 90° exactly, else 0."""
    d = angular_difference(CLASS_ANGLES_DEG[:, None], CLASS_ANGLES_DEG[None, :])
    return np.where(np.isclose(d, 90.0), 0.5, (d < 90.0).astype(float))


def combine_looks(p_whole: np.ndarray, p_end: np.ndarray) -> np.ndarray:
    """(24,) class probabilities from the whole car's look and the near end's look.

    The two looks are two pieces of evidence of which way the car faces. Each class's
    probability from the whole car is weighed by the near end's probability that the car faces
    that class's way: its mass within 90° of the class (half of it at 90° exactly). Where both
    looks agree the call stands; where they disagree, the surer one wins. The angle comes from
    the whole car, which sees more of it."""
    p_whole = np.asarray(p_whole, dtype=np.float64)
    out = p_whole * (facing_halves() @ np.asarray(p_end, dtype=np.float64))
    total = out.sum()
    return (out / total if total > 0 else p_whole).astype(np.float32)


def write_end_looks(src: str | Path, dst: str | Path, seed: int = 0,
                    keep_range: tuple[float, float] = END_KEEP_RANGE) -> int:
    """Write the end looks of a set of framed renders: a copy of ``src`` (``render-dataset``'s
    folder) holding only its framed three-quarter views, each image's far part painted grey
    (:func:`end_look` at the image's own view, the share kept drawn from ``keep_range``), with
    their manifest rows (labels, split and box unchanged) and ``dataset.json`` marked
    :data:`END_LOOK_KEY`. Everything follows from ``seed``.

    Returns:
        the number of end looks written.
    Raises:
        ViewError: ``src`` is no data set folder, or ``dst`` exists.
    """
    import cv2

    from carbody.view.dataset import read_manifest, row_box

    src, dst = Path(src), Path(dst)
    if not (src / "manifest.csv").is_file() or not (src / "dataset.json").is_file():
        raise ViewError(f"{src}: no manifest.csv and dataset.json (not a render-dataset folder)")
    if dst.exists():
        raise ViewError(f"{dst}: exists; end looks are written to a new folder")
    rows = read_manifest(src)
    fields = list(rows[0])
    rng = np.random.default_rng(seed)
    tmp = dst.with_name(f".{dst.name}.tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    kept = []
    for row in rows:
        box = row_box(row)
        if box is None or not is_three_quarter(float(row["theta_deg"])):
            continue
        keep = float(rng.uniform(*keep_range))
        image = cv2.imread(str(src / row["file"]), cv2.IMREAD_COLOR)
        if image is None:
            raise ViewError(f"{src / row['file']}: not a readable image")
        out = tmp / row["file"]
        out.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(out), end_look(image, box, float(row["theta_deg"]), keep))
        kept.append(row)
    with open(tmp / "manifest.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        writer.writerows(kept)
    meta = json.loads((src / "dataset.json").read_text())
    meta[END_LOOK_KEY] = {"source": src.name, "seed": seed, "keep_range": list(keep_range),
                          "three_quarter_margin_deg": THREE_QUARTER_MARGIN_DEG, "images": len(kept)}
    (tmp / "dataset.json").write_text(json.dumps(meta, indent=1) + "\n")
    tmp.rename(dst)
    return len(kept)
