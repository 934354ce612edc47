"""The view classifier's MobileNetV2 forward pass in plain numpy: no torch at inference time.

``import torch`` alone costs seconds of CPU in a fresh process (1.6 to 4.4 s measured), the
largest single cost of ``carbody reconstruct`` on one photo. The network is small (2.25 M
parameters, 96 × 96 input as shipped), so numpy runs it in a few milliseconds per image from
the same weights, exported once at packaging time (with torch) to an ``.npz``:

    from carbody.view.numpy_net import export_weights, probabilities
    export_weights("view_mobilenetv2.pt", "view_mobilenetv2.npz")     # torch, once
    p = probabilities(x)     # x (B, 64, 64, 3) uint8 from carbody.view.train.to_square_input

The export folds every BatchNorm into its conv: the conv's weight is stored as the ``.pt``
holds it (float16, so no rounding is added) beside a float32 per-output-channel scale
γ/√(σ² + ε) and a float32 bias β − μ·γ/√(σ² + ε); the loader multiplies the scale into the
float32 weight once, so the forward pass is conv + bias (+ ReLU6) and nothing else. Storing
the already-folded weight in float16 instead would round it a second time (measured
max |Δp| 1.0e-3 against torch, against 4e-7 this way).

The forward pass is channels-last (N, H, W, C): a 1×1 conv is one matmul over all pixels, the
3×3 depthwise conv is nine shifted (strided) views of the zero-padded input times a (C,)
weight, and the stem's 3×3 stride-2 conv is a matmul over its nine stacked views (im2col).

The ``.npz`` holds ``meta`` (JSON: format, number of classes, width multiplier, input size,
normalisation, class angles, the layer list, the source file's SHA-256) and per layer ``i``:
``w{i:02d}`` (float16; 1×1: (Cin, Cout); depthwise: (3, 3, C); stem: (9·Cin, Cout) in
(dy, dx, cin) order; linear: (Cin, classes)), ``s{i:02d}`` (float32 (Cout,), 1 for the linear
layer) and ``b{i:02d}`` (float32 (Cout,)).
"""
from __future__ import annotations

import functools
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from carbody.errors import ViewError
from carbody.view.labels import MIRROR_PERMUTATION, N_CLASSES

#: The exported weights shipped with the package (written from ``view_mobilenetv2.pt``).
SHIPPED_NPZ = Path(__file__).resolve().parent / "weights" / "view_mobilenetv2.npz"

#: The ``format`` field of the ``.npz`` this module writes and reads.
NPZ_FORMAT = "carbody-view-mobilenetv2-numpy/1"

#: BatchNorm2d's default ε, which the network is built with.
BN_EPS = 1e-5


# ------------------------------------------------------------------------------------- export

def export_weights(pt_path: str | Path, npz_path: str | Path) -> dict:
    """Write the ``.npz`` of a ``.pt`` view-classifier weights file, BatchNorms folded.

    Needs torch (run at training or packaging time). The layer list is read off the torch
    network built from the file, so the strides, groups and skips are the ones it runs.

    Returns:
        The ``meta`` dict written to the file.

    Raises:
        ViewError: not a view-classifier weights file.
    """
    import torch
    from torch import nn

    from carbody.view.network import build_mobilenet_v2

    pt_path = Path(pt_path)
    try:
        payload = torch.load(pt_path, map_location="cpu", weights_only=True)
        num_classes = int(payload["num_classes"])
        width_mult = float(payload.get("width_mult", 1.0))
        model = build_mobilenet_v2(num_classes, width_mult=width_mult)
        model.load_state_dict(payload["state_dict"])   # keeps the file's float16 values
    except Exception as exc:  # a corrupt file can fail in many ways inside torch
        raise ViewError(f"{pt_path}: not a view-classifier weights file ({type(exc).__name__})") from None
    model.eval()

    arrays: dict[str, np.ndarray] = {}
    layers: list[dict] = []

    def add(conv: nn.Conv2d, bn: nn.BatchNorm2d, relu6: bool, residual: str | None = None) -> None:
        i = len(layers)
        w = conv.weight.detach().numpy()                           # (Cout, Cin/groups, k, k)
        var = bn.running_var.detach().double().numpy()
        scale = bn.weight.detach().double().numpy() / np.sqrt(var + bn.eps)
        bias = bn.bias.detach().double().numpy() - bn.running_mean.detach().double().numpy() * scale
        k, stride, groups = conv.kernel_size[0], conv.stride[0], conv.groups
        if groups == 1 and k == 1:
            op, stored = "pointwise", w[:, :, 0, 0].T                # (Cin, Cout)
        elif groups == conv.in_channels == conv.out_channels and k == 3:
            op, stored = "depthwise", w[:, 0].transpose(1, 2, 0)     # (3, 3, C)
        elif groups == 1 and k == 3:
            op, stored = "conv3x3", w.transpose(2, 3, 1, 0).reshape(9 * conv.in_channels, -1)
        else:
            raise ViewError(f"{pt_path}: a {k}x{k} conv with {groups} groups is not a MobileNetV2 layer")
        arrays[f"w{i:02d}"] = np.ascontiguousarray(stored, dtype=np.float16)
        arrays[f"s{i:02d}"] = scale.astype(np.float32)
        arrays[f"b{i:02d}"] = bias.astype(np.float32)
        layers.append({"op": op, "stride": int(stride), "relu6": relu6, "residual": residual})

    def add_conv_bn_relu(seq: nn.Sequential, residual: str | None = None) -> None:
        add(seq[0], seq[1], relu6=True, residual=residual)

    for feature in model.features:
        if isinstance(feature, nn.Sequential):                     # stem or last 1×1 conv
            add_conv_bn_relu(feature)
            continue
        parts = list(feature.conv)
        skip = bool(feature.use_skip)
        for j, part in enumerate(parts[:-2]):
            add_conv_bn_relu(part, residual="save" if skip and j == 0 else None)
        add(parts[-2], parts[-1], relu6=False, residual="add" if skip else None)
    linear = model.classifier[-1]
    i = len(layers)
    arrays[f"w{i:02d}"] = linear.weight.detach().numpy().T.astype(np.float16)
    arrays[f"s{i:02d}"] = np.ones(linear.out_features, np.float32)
    arrays[f"b{i:02d}"] = linear.bias.detach().float().numpy()
    layers.append({"op": "linear", "stride": 1, "relu6": False, "residual": None})

    meta = {"format": NPZ_FORMAT, "num_classes": num_classes, "width_mult": width_mult,
            "input_size": int(payload.get("input_size", 64)), "mean": float(payload.get("mean", 0.5)),
            "std": float(payload.get("std", 0.25)), "classes_deg": list(payload.get("classes_deg", [])),
            "temperature": float(payload.get("temperature", 1.0)), "layers": layers, "source": pt_path.name,
            "source_sha256": hashlib.sha256(pt_path.read_bytes()).hexdigest()}
    np.savez_compressed(npz_path, meta=np.array(json.dumps(meta)), **arrays)
    return meta


# ------------------------------------------------------------------------------------- forward

def _relu6(x: np.ndarray) -> np.ndarray:
    return np.clip(x, 0.0, 6.0, out=x)  # (one pass: a third of maximum-then-minimum's time here)


def _padded(x: np.ndarray) -> np.ndarray:
    """(N, H + 2, W + 2, C) ``x`` with a one-pixel zero border (the convs' padding 1)."""
    n, h, w, c = x.shape
    xp = np.zeros((n, h + 2, w + 2, c), np.float32)
    xp[:, 1:-1, 1:-1] = x
    return xp


def _tap(xp: np.ndarray, dy: int, dx: int, ho: int, wo: int, stride: int) -> np.ndarray:
    """The (N, ho, wo, C) view of a padded input a 3×3 kernel's tap (dy, dx) reads."""
    return xp[:, dy:dy + stride * (ho - 1) + 1:stride, dx:dx + stride * (wo - 1) + 1:stride]


def _out_size(side: int, stride: int) -> int:
    return (side - 1) // stride + 1                                 # kernel 3, padding 1


def _conv3x3(x: np.ndarray, w: np.ndarray, b: np.ndarray, stride: int) -> np.ndarray:
    n, h, wd, c = x.shape
    ho, wo = _out_size(h, stride), _out_size(wd, stride)
    xp = _padded(x)
    cols = np.empty((n, ho, wo, 3, 3, c), np.float32)
    for dy in range(3):
        for dx in range(3):
            cols[:, :, :, dy, dx] = _tap(xp, dy, dx, ho, wo, stride)
    return (cols.reshape(-1, 9 * c) @ w + b).reshape(n, ho, wo, -1)


def _depthwise(x: np.ndarray, w: np.ndarray, b: np.ndarray, stride: int) -> np.ndarray:
    n, h, wd, c = x.shape
    ho, wo = _out_size(h, stride), _out_size(wd, stride)
    xp = _padded(x)
    out = np.multiply(_tap(xp, 0, 0, ho, wo, stride), w[0, 0])
    tmp = np.empty_like(out)
    for dy in range(3):
        for dx in range(3):
            if dy or dx:
                out += np.multiply(_tap(xp, dy, dx, ho, wo, stride), w[dy, dx], out=tmp)
    out += b
    return out


def _pointwise(x: np.ndarray, w: np.ndarray, b: np.ndarray) -> np.ndarray:
    n, h, wd, c = x.shape
    out = x.reshape(-1, c) @ w
    out += b
    return out.reshape(n, h, wd, -1)


@dataclass
class NumpyMobileNetV2:
    """The exported MobileNetV2, run with numpy.

    Attributes:
        layers: one dict per layer (``op``: conv3x3, depthwise, pointwise or linear;
            ``stride``; ``relu6``; ``residual``: "save" on a block's first layer, "add" on
            its last, when the block has a skip connection).
        weights: one float32 array per layer, BatchNorm scale folded in (shapes: module doc).
        biases: one (Cout,) float32 array per layer.
        meta: the file's metadata (``num_classes``, ``input_size``, ``mean``, ``std``, ...).
    """

    layers: list[dict]
    weights: list[np.ndarray]
    biases: list[np.ndarray]
    meta: dict

    @classmethod
    def from_npz(cls, path: str | Path) -> "NumpyMobileNetV2":
        """The network of an ``.npz`` written by :func:`export_weights`.

        Raises:
            ViewError: not such a file.
        """
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as f:
                meta = json.loads(str(f["meta"]))
                if meta.get("format") != NPZ_FORMAT:
                    raise ValueError(meta.get("format"))
                layers = meta["layers"]
                weights = [f[f"w{i:02d}"].astype(np.float32) * f[f"s{i:02d}"] for i in range(len(layers))]
                biases = [f[f"b{i:02d}"].astype(np.float32) for i in range(len(layers))]
        except Exception as exc:  # missing, truncated, another format
            raise ViewError(f"{path}: not a numpy view-classifier weights file ({type(exc).__name__})") from None
        return cls(layers, weights, biases, meta)

    def network_input(self, images: np.ndarray) -> np.ndarray:
        """(B, S, S, 3) float32 network input from (B, S, S, 3) uint8 square pictures:
        (x / 255 − mean) / std in float32, the same values as ``carbody.view.train.to_tensor``
        (which is channels-first)."""
        x = np.asarray(images).astype(np.float32) / np.float32(255.0)
        x -= np.float32(self.meta["mean"])
        x /= np.float32(self.meta["std"])
        return x

    def logits(self, x: np.ndarray) -> np.ndarray:
        """(N, classes) float32 logits of an (N, H, W, 3) or (N, 3, H, W) float32 batch (already
        normalised; channels-first when axis 1 has 3 entries and the last axis does not)."""
        x = np.asarray(x, dtype=np.float32)
        if x.ndim != 4 or 3 not in (x.shape[1], x.shape[3]):
            raise ViewError(f"the network takes (N, H, W, 3) or (N, 3, H, W) input, not {x.shape}")
        if x.shape[3] != 3:
            x = x.transpose(0, 2, 3, 1)
        saved = None
        for layer, w, b in zip(self.layers, self.weights, self.biases):
            op = layer["op"]
            if layer["residual"] == "save":
                saved = x
            if op == "pointwise":
                x = _pointwise(x, w, b)
            elif op == "depthwise":
                x = _depthwise(x, w, b, layer["stride"])
            elif op == "conv3x3":
                x = _conv3x3(x, w, b, layer["stride"])
            else:                                                   # linear, after the pool
                x = x.mean(axis=(1, 2)) @ w + b
            if layer["relu6"]:
                x = _relu6(x)
            if layer["residual"] == "add":
                x += saved
        return x


def softmax(logits: np.ndarray) -> np.ndarray:
    """Row-wise softmax of (N, K) logits."""
    z = np.exp(logits - logits.max(axis=1, keepdims=True))
    return z / z.sum(axis=1, keepdims=True)


@functools.lru_cache(maxsize=4)
def _load(path_text: str, mtime_ns: int) -> NumpyMobileNetV2:  # mtime_ns: cache key only
    net = NumpyMobileNetV2.from_npz(path_text)
    if int(net.meta["num_classes"]) != N_CLASSES:
        raise ViewError(f"{path_text}: has {net.meta['num_classes']} classes, expected {N_CLASSES}")
    return net


def load_numpy_classifier(npz_path: str | Path | None = None) -> NumpyMobileNetV2:
    """The numpy network of an ``.npz`` (default: the shipped one), built once per file and
    process (and again when the file changes).

    Raises:
        ViewError: missing or bad file, or not 24 classes.
    """
    from carbody.inputs import MAX_WEIGHTS_BYTES, input_file

    path = input_file(Path(npz_path) if npz_path else SHIPPED_NPZ, "weights file", ViewError, MAX_WEIGHTS_BYTES)
    return _load(str(path), path.stat().st_mtime_ns)


def probabilities(images: np.ndarray, npz_path: str | Path | None = None,
                  mirror_average: bool = True, temperature: float | None = None) -> np.ndarray:
    """(B, 24) class probabilities of (B, S, S, 3) uint8 square pictures (from
    ``carbody.view.train.to_square_input``), as ``carbody.view.predict.predict_probabilities``
    gives them (float32) but through the numpy network: with ``mirror_average``, one pass over
    the pictures and their mirror images, the mirror's classes mapped back and the two averaged.
    ``temperature`` divides the logits (None: the calibrated one the weights carry, else 1)."""
    net = load_numpy_classifier(npz_path)
    x = np.asarray(images)
    if x.ndim != 4 or x.shape[3] != 3:
        raise ViewError(f"probabilities takes (B, S, S, 3) square pictures, not {x.shape}")
    n = len(x)
    if mirror_average:
        x = np.concatenate([x, x[:, :, ::-1]])
    t = float(net.meta.get("temperature", 1.0)) if temperature is None else float(temperature)
    p = softmax(net.logits(net.network_input(x)).astype(np.float64) / t)
    if mirror_average:
        p = (p[:n] + p[n:][:, MIRROR_PERMUTATION]) / 2
    return p.astype(np.float32)


# ------------------------------------------------------------------------------------- hook

def numpy_weights_for(weights: str | Path | None) -> Path | None:
    """The ``.npz`` that ``predict_probabilities(..., weights)`` can run instead of torch, or
    None (a ``.pt`` file: torch). ``weights`` None is the shipped ``.pt``, whose export
    :data:`SHIPPED_NPZ` is (tests/test_numpy_net.py checks they match)."""
    if weights is None:
        return SHIPPED_NPZ if SHIPPED_NPZ.is_file() else None
    return Path(weights) if Path(weights).suffix == ".npz" else None
