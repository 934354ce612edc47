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


def predict_probabilities(images: list | np.ndarray, weights: str | Path | None = None,
                          mirror_average: bool = True) -> np.ndarray:
    """(B, 24) class probabilities of a batch of pictures (paths or arrays): through the numpy
    network (:mod:`carbody.view.numpy_net`, no torch to import) for the shipped weights or an
    ``.npz``, through torch for a ``.pt`` file."""
    from carbody.view.numpy_net import numpy_weights_for, probabilities
    from carbody.view.train import to_square_input

    x = np.stack([to_square_input(read_image(im)) for im in images])   # bad input first
    npz = numpy_weights_for(weights)
    if npz is not None:
        return probabilities(x, npz, mirror_average)
    import torch

    from carbody.view.train import to_tensor

    model, _ = load_classifier(str(weights) if weights else None)
    n = len(x)
    if mirror_average:          # one forward pass over the pictures and their mirror images
        x = np.concatenate([x, x[:, :, ::-1]])
    with torch.inference_mode():
        p = torch.softmax(model(to_tensor(x)), 1).numpy()
    if mirror_average:
        p = (p[:n] + p[n:][:, MIRROR_PERMUTATION]) / 2
    return p


def predict_view(image, weights: str | Path | None = None, mirror_average: bool = True) -> ViewPrediction:
    """The view angle of one car picture (path or array); see :class:`ViewPrediction`.

    Raises:
        ImageError: unreadable, empty or tiny picture.
        ViewError: missing or bad weights.
    """
    p = predict_probabilities([image], weights, mirror_average)[0]
    k = int(np.argmax(p))
    return ViewPrediction(k, float(CLASS_ANGLES_DEG[k]), continuous_estimate(p), float(p[k]), p)
