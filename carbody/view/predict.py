"""Tell the view angle of a car photo with the shipped (or a given) MobileNetV2.

    from carbody.view import predict_view
    p = predict_view("photo.jpg")          # path or (h, w[, 1|3|4]) uint8 array
    p.class_deg, p.theta_deg, p.probabilities

Grayscale pictures are repeated to three channels; RGBA pictures are put on white; 16-bit
pictures are scaled to 8 bits. The prediction averages the picture and its mirror image (with
mirrored classes), which makes left/right mistakes rarer at little cost.
"""
from __future__ import annotations

import contextlib
import functools
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from carbody.errors import ImageError, ViewError
from carbody.view.labels import CLASS_ANGLES_DEG, MIRROR_PERMUTATION, N_CLASSES, continuous_estimate

#: The weights shipped with the package.
SHIPPED_WEIGHTS = Path(__file__).resolve().parent / "weights" / "view_mobilenetv2.pt"

#: Pictures smaller than this on either side are refused (pixels).
MIN_IMAGE_SIDE = 16

#: Pictures with more pixels than this are refused, from the file's header before decoding it:
#: a 108-megapixel phone photo fits; a larger one (or a "decompression bomb", a small file
#: whose header claims 100000 x 100000 pixels) would take gigabytes to decode and draw on, for
#: no better fit (the fit needs a few hundred pixels across the car): resize it first.
MAX_IMAGE_PIXELS = 120_000_000


@dataclass
class ViewPrediction:
    """The classifier's answer.

    Attributes:
        class_index: 0..23, the class k of θ_k = 15°·k.
        class_deg: θ_k in degrees (0 front, 90 left side, 180 rear, 270 right side).
        theta_deg: continuous estimate in [0, 360), degrees.
        confidence: probability of the top class.
        probabilities: (24,) float, class probabilities (sum 1).
    """

    class_index: int
    class_deg: float
    theta_deg: float
    confidence: float
    probabilities: np.ndarray

    @property
    def side(self) -> str:
        """``front``, ``rear``, ``left`` or ``right`` (which side of the car the camera sees)."""
        if self.class_deg in (0.0, 180.0):
            return "front" if self.class_deg == 0.0 else "rear"
        return "left" if self.class_deg < 180.0 else "right"

    @property
    def paper_class_deg(self) -> float:
        """The paper's 13-class label (0°–180°): right-side views fold onto their mirror."""
        return self.class_deg if self.class_deg <= 180.0 else 360.0 - self.class_deg

    def as_dict(self) -> dict:
        return {"class_index": self.class_index, "class_deg": self.class_deg, "theta_deg": round(self.theta_deg, 2),
                "side": self.side, "paper_class_deg": self.paper_class_deg,
                "confidence": round(self.confidence, 4),
                "probabilities": {f"{int(a)}": round(float(p), 4) for a, p in zip(CLASS_ANGLES_DEG, self.probabilities)}}


def exif_orientation(path: str | Path) -> int:
    """The EXIF orientation tag (1–8) of an image file, 1 when it has none or it cannot be read.

    A phone stores a photo as its sensor read it and tags how to turn it upright; viewers and
    annotation tools (labelme, CVAT) show it turned, so keypoints are marked on the turned
    picture.
    """
    try:
        with open_picture(path) as im:
            value = int(im.getexif().get(0x0112, 1))
    except Exception:  # no EXIF, or not a format PIL reads: as stored
        return 1
    return value if 1 <= value <= 8 else 1


def upright(arr: np.ndarray, orientation: int) -> np.ndarray:
    """The picture ``arr`` (h, w[, c]) as an EXIF ``orientation`` (1–8) says it is seen."""
    if orientation in (5, 6, 7, 8):
        arr = np.swapaxes(arr, 0, 1)                # transposed, 5–8 are 1–4 below
        orientation = {5: 1, 6: 2, 7: 3, 8: 4}[orientation]
    if orientation in (2, 3):
        arr = arr[:, ::-1]
    if orientation in (3, 4):
        arr = arr[::-1]
    return arr


@contextlib.contextmanager
def open_picture(path: str | Path):
    """PIL's lazy view of an image file (header and EXIF; pixels only when asked), without PIL's
    warning about a large picture (carbody's own limit is :data:`MAX_IMAGE_PIXELS`)."""
    from PIL import Image

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)
        with Image.open(path) as im:
            yield im


def check_stored_size(path: Path) -> None:
    """Refuse an image file whose header states more than :data:`MAX_IMAGE_PIXELS` pixels,
    without decoding it (a header PIL cannot read is left to OpenCV, whose own limit is 2^30)."""
    from PIL import Image

    try:
        with open_picture(path) as im:
            size = im.size
    except Image.DecompressionBombError:  # PIL's own limit lies above ours
        check_pixel_count((MAX_IMAGE_PIXELS + 1, 1), path)
    except Exception:  # not a format PIL reads
        return
    check_pixel_count(size, path)


def check_pixel_count(size: tuple[int, int] | None, name) -> None:
    """Refuse a picture of more than :data:`MAX_IMAGE_PIXELS` pixels (``size`` (width, height))."""
    if size is not None and size[0] * size[1] > MAX_IMAGE_PIXELS:
        w, h = size
        shown = f"{w} x {h} px is" if h > 1 else "the picture has"
        raise ImageError(f"{name}: {shown} more than the {MAX_IMAGE_PIXELS / 1e6:.0f} megapixels "
                         "carbody reads; resize the photo (and mark it at that size)")


def read_image(image) -> np.ndarray:
    """(h, w, 3) uint8 RGB from a path or an array (gray, gray+alpha, RGB, RGBA; 8 or 16 bit).

    A file is turned upright as its EXIF orientation says (:func:`exif_orientation`), as photo
    viewers and annotation tools show it.

    Raises:
        ImageError: missing or empty file, not a regular file, not an image, empty or tiny
            picture, or more than :data:`MAX_IMAGE_PIXELS` pixels (refused from the file's
            header, before decoding).
    """
    import cv2

    if isinstance(image, (str, Path)):
        from carbody.inputs import input_file

        path = input_file(image, "image file", ImageError)
        check_stored_size(path)
        data = np.fromfile(path, dtype=np.uint8)
        if data.size == 0:
            raise ImageError(f"{path}: the file is empty")
        arr = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
        if arr is None:
            raise ImageError(f"{path}: not an image (cannot decode it)")
        if arr.ndim == 3 and arr.shape[2] >= 3:    # OpenCV decodes to BGR(A)
            arr = cv2.cvtColor(arr, cv2.COLOR_BGRA2RGBA if arr.shape[2] == 4 else cv2.COLOR_BGR2RGB)
        arr = upright(arr, exif_orientation(path))  # IMREAD_UNCHANGED leaves the EXIF turn to us
        name = str(path)
    else:
        arr = np.asarray(image)
        name = "image"
    if arr.size == 0 or arr.ndim not in (2, 3):
        raise ImageError(f"{name}: empty or not a picture (shape {arr.shape})")
    check_pixel_count(arr.shape[1::-1], name)
    if arr.ndim == 3 and arr.shape[2] not in (1, 2, 3, 4):
        raise ImageError(f"{name}: {arr.shape[2]} channels (need 1, 2, 3 or 4)")
    h, w = arr.shape[:2]
    if min(h, w) < MIN_IMAGE_SIDE:
        raise ImageError(f"{name}: {w}x{h} px is too small (need at least {MIN_IMAGE_SIDE} px a side)")
    if arr.dtype == np.uint16:
        arr = (arr / 257.0).round().astype(np.uint8)
    elif arr.dtype == bool:
        arr = arr.astype(np.uint8) * 255
    elif np.issubdtype(arr.dtype, np.floating):
        if not np.all(np.isfinite(arr)):
            raise ImageError(f"{name}: holds NaN or infinite values")
        arr = np.clip(arr * (255.0 if arr.max() <= 1.0 else 1.0), 0, 255).round().astype(np.uint8)
    elif arr.dtype != np.uint8:
        arr = np.clip(arr, 0, 255).astype(np.uint8)
    if arr.ndim == 2:
        arr = arr[..., None]
    c = arr.shape[2]
    if c in (2, 4):                                 # alpha: put the picture on white
        alpha = arr[..., -1:].astype(np.float32) / 255.0
        colour = arr[..., :-1].astype(np.float32)
        arr = (colour * alpha + 255.0 * (1 - alpha)).round().astype(np.uint8)
        c -= 1
    if c == 1:
        arr = np.repeat(arr, 3, axis=2)
    return np.ascontiguousarray(arr)


def load_classifier(weights: str | None = None):
    """(model in eval mode, metadata dict) from a weights file (default: the shipped one).

    The network is built once per file and process (and again when the file changes).

    Raises:
        ViewError: missing or unreadable weights file.
    """
    from carbody.inputs import MAX_WEIGHTS_BYTES, input_file

    path = input_file(Path(weights) if weights else SHIPPED_WEIGHTS, "weights file", ViewError, MAX_WEIGHTS_BYTES)
    return _load_classifier(str(path), path.stat().st_mtime_ns)


@functools.lru_cache(maxsize=4)
def _load_classifier(path_text: str, mtime_ns: int):  # mtime_ns: cache key only
    import torch

    from carbody.view.network import build_mobilenet_v2

    path = Path(path_text)
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
        model = build_mobilenet_v2(int(payload["num_classes"]), width_mult=float(payload.get("width_mult", 1.0)))
        model.load_state_dict({k: v.float() if v.is_floating_point() else v
                               for k, v in payload["state_dict"].items()})
    except Exception as exc:  # a corrupt file can fail in many ways inside torch
        raise ViewError(f"{path}: not a view-classifier weights file ({type(exc).__name__})") from None
    if int(payload["num_classes"]) != N_CLASSES:
        raise ViewError(f"{path}: has {payload['num_classes']} classes, expected {N_CLASSES}")
    model.eval()
    meta = {k: v for k, v in payload.items() if k != "state_dict"}
    return model, meta


#: A car's box fills this fraction of the square crop's side (the renders: 0.6–0.95 of the frame).
BOX_FILL = 0.8

#: The box of the keypoints grows by this fraction of its larger side on every side before the
#: crop: the marks sit inside the car's outline (pillars, arches, bumper centres), and a photo's
#: marks often leave the far end of the car unmarked.
KEYPOINT_BOX_MARGIN = 0.12


#: A car's box may run off the picture (a car cut by the frame), but not past this many times
#: its larger side: the square cropped round it would be mostly made-up border.
MAX_BOX_TO_PICTURE = 3.0


def check_box(box, image_size: tuple[int, int] | None = None) -> tuple[float, float, float, float]:
    """(x0, y0, x1, y1) pixels as floats, checked: finite, x1 > x0, y1 > y0, overlapping the picture
    and at most :data:`MAX_BOX_TO_PICTURE` times its size.

    Raises:
        ViewError: anything else.
    """
    try:
        b = np.asarray(box, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ViewError(f"a box is four numbers x0 y0 x1 y1, got {box!r}") from None
    if b.shape != (4,) or not np.all(np.isfinite(b)):
        raise ViewError(f"a box is four finite numbers x0 y0 x1 y1, got {box!r}")
    x0, y0, x1, y1 = (float(v) for v in b)
    if not (x1 - x0 >= 2 and y1 - y0 >= 2):
        raise ViewError(f"box {x0:g} {y0:g} {x1:g} {y1:g} is empty (need x1 > x0 and y1 > y0, 2 px at least)")
    if image_size is not None:
        w, h = image_size
        if x1 <= 0 or y1 <= 0 or x0 >= w or y0 >= h:
            raise ViewError(f"box {x0:g} {y0:g} {x1:g} {y1:g} lies outside the {w}x{h} px picture")
        if max(x1 - x0, y1 - y0) > MAX_BOX_TO_PICTURE * max(w, h):  # its square would be a vast crop
            raise ViewError(f"box {x0:g} {y0:g} {x1:g} {y1:g} is more than {MAX_BOX_TO_PICTURE:g} times "
                            f"the {w}x{h} px picture")
    return x0, y0, x1, y1


def keypoint_box(points, margin: float = KEYPOINT_BOX_MARGIN) -> tuple[float, float, float, float] | None:
    """The box (x0, y0, x1, y1) of keypoints ({name: (u, v)} or (N, 2) pixels), grown by
    ``margin`` × its larger side on every side; None when the finite ones span no box (fewer
    than two, or all within 2 px): then the whole picture is the best guess, and the fit says
    what is wrong with the marks."""
    try:
        uv = np.asarray(list(points.values()) if hasattr(points, "values") else points, dtype=float).reshape(-1, 2)
    except (TypeError, ValueError):
        return None
    uv = uv[np.all(np.isfinite(uv), axis=1)]
    if len(uv) < 2:
        return None
    (x0, y0), (x1, y1) = uv.min(0), uv.max(0)
    pad = margin * max(x1 - x0, y1 - y0)
    if max(x1 - x0, y1 - y0) < 2:
        return None
    pad_y = max(pad, (2 - (y1 - y0)) / 2)      # marks on one line still make a box
    pad_x = max(pad, (2 - (x1 - x0)) / 2)
    return (float(x0 - pad_x), float(y0 - pad_y), float(x1 + pad_x), float(y1 + pad_y))


def crop_to_box(image: np.ndarray, box, fill: float = BOX_FILL) -> np.ndarray:
    """The square around a car's box (x0, y0, x1, y1) pixels in which the box's larger side
    spans ``fill`` of the square, as the renders frame their cars: (s, s, 3) uint8. Parts of the
    square outside the picture repeat its border.

    Raises:
        ViewError: a bad box (see :func:`check_box`).
    """
    import cv2

    h, w = image.shape[:2]
    x0, y0, x1, y1 = check_box(box, (w, h))
    side = max(x1 - x0, y1 - y0) / fill
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    a0, b0 = int(round(cx - side / 2)), int(round(cy - side / 2))
    s = max(2, int(round(side)))
    pad = ((max(0, -b0), max(0, b0 + s - h)), (max(0, -a0), max(0, a0 + s - w)))
    crop = image[max(0, b0):min(h, b0 + s), max(0, a0):min(w, a0 + s)]
    if any(pad[0]) or any(pad[1]):
        crop = cv2.copyMakeBorder(crop, *pad[0], *pad[1], cv2.BORDER_REPLICATE)
    return np.ascontiguousarray(crop)


def predict_probabilities(images: list | np.ndarray, weights: str | Path | None = None,
                          mirror_average: bool = True, boxes: list | None = None,
                          temperature: float | None = None, end_looks: bool = True) -> np.ndarray:
    """(B, 24) class probabilities of a batch of pictures (paths or arrays): through the exported
    network in ONNX Runtime (:mod:`carbody.view.onnx_net`, no torch to import) for the
    shipped weights or an ``.onnx``, through torch for a ``.pt`` file.

    Args:
        boxes: per picture, None or the car's box (x0, y0, x1, y1) pixels to crop to
            (:func:`crop_to_box`).
        temperature: divides the logits before the softmax; None: the weights' calibrated one
            (1 when they have none).
        end_looks: a picture with a box seen three-quarter on gets a second look at its near end
            alone, which settles which way the car faces (:mod:`carbody.view.ends`), when the
            weights were trained on such looks.
    """
    from carbody.view.ends import END_LOOK_KEY, combine_looks, end_look, second_look_view
    from carbody.view.onnx_net import onnx_weights_for, probabilities
    from carbody.view.train import INPUT_SIZE, to_square_input

    boxes = list(boxes) if boxes is not None else [None] * len(images)
    if len(boxes) != len(images):
        raise ViewError(f"{len(boxes)} boxes for {len(images)} pictures")
    if temperature is not None and not float(temperature) > 0:
        raise ViewError(f"the temperature must be positive, got {temperature}")
    pics = [read_image(im) for im in images]
    exported = onnx_weights_for(weights)
    if exported is not None:
        from carbody.view.onnx_net import load_onnx_classifier

        meta = load_onnx_classifier(exported).meta
        run = lambda x: probabilities(x, exported, mirror_average, temperature)  # noqa: E731
    else:
        model, meta = load_classifier(str(weights) if weights else None)
        run = lambda x: _torch_probabilities(model, meta, x, mirror_average, temperature)  # noqa: E731
    size = int(meta.get("input_size", INPUT_SIZE))
    p = run(np.stack([to_square_input(pic if b is None else crop_to_box(pic, b), size) for pic, b in zip(pics, boxes)]))
    if end_looks and meta.get(END_LOOK_KEY):
        views = [second_look_view(b, q) for b, q in zip(boxes, p)]
        second = [i for i, v in enumerate(views) if v is not None]
        if second:
            ends = run(np.stack([to_square_input(crop_to_box(end_look(pics[i], boxes[i], views[i]), boxes[i]), size)
                                 for i in second]))
            for i, q in zip(second, ends):
                p[i] = combine_looks(p[i], q)
    return p


def _torch_probabilities(model, meta: dict, x: np.ndarray, mirror_average: bool,
                         temperature: float | None) -> np.ndarray:
    """(B, 24) float32 class probabilities of (B, S, S, 3) uint8 square pictures through a torch
    model (:func:`predict_probabilities`)."""
    import torch

    from carbody.view.train import to_tensor

    t = float(meta.get("temperature", 1.0)) if temperature is None else float(temperature)
    if not t > 0:
        raise ViewError(f"the temperature must be positive, got {t}")
    n = len(x)
    if mirror_average:          # one forward pass over the pictures and their mirror images
        x = np.concatenate([x, x[:, :, ::-1]])
    with torch.inference_mode():
        p = torch.softmax(model(to_tensor(x)) / t, 1).numpy()
    if mirror_average:
        p = (p[:n] + p[n:][:, MIRROR_PERMUTATION]) / 2
    return p


def predict_view(image, weights: str | Path | None = None, mirror_average: bool = True,
                 box=None, marks=None, end_looks: bool = True) -> ViewPrediction:
    """The view angle of one car picture (path or array); see :class:`ViewPrediction`.

    Args:
        box: the car's box (x0, y0, x1, y1) pixels, e.g. :func:`keypoint_box` of its marks; the
            picture is cropped to it as the renders frame their cars (much better on photos
            where the car fills little of the frame). None: the whole picture.
        marks: names of the keypoints marked on the picture (or a {name: (u, v)} map): their
            view likelihood (:mod:`carbody.view.marks`) multiplies the probabilities, which
            settles front against rear and left against right.

    Raises:
        ImageError: unreadable, empty or tiny picture.
        ViewError: missing or bad weights, a bad box.
    """
    p = predict_probabilities([image], weights, mirror_average, boxes=[box], end_looks=end_looks)[0]
    if marks:
        from carbody.view.marks import combine_with_marks

        p = combine_with_marks(p, list(marks))
    k = int(np.argmax(p))
    return ViewPrediction(k, float(CLASS_ANGLES_DEG[k]), continuous_estimate(p), float(p[k]), p)
