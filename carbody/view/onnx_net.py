"""The view classifier without torch at inference: the exported network run by ONNX Runtime.

``import torch`` alone costs seconds of CPU in a fresh process (1.6 to 4.4 s measured), the
largest single cost of ``carbody reconstruct`` on one photo. The network is small (2.25 M
parameters, 128 × 128 input as shipped), so it is exported once at packaging time (with torch
and the ``onnx`` package) to an ONNX file, which ONNX Runtime (``onnxruntime``) reads and runs
in a few milliseconds per picture. It ran the shipped network twice as fast as OpenCV's DNN
module, which ran it before (``benchmarks/bench_view.py --speed``):

    from carbody.view.onnx_net import export_weights, probabilities
    export_weights("view_mobilenetv2.pt", "view_mobilenetv2.onnx")    # torch + onnx, once
    p = probabilities(x)     # x (B, 128, 128, 3) uint8 from carbody.view.train.to_square_input

The export folds every BatchNorm into its conv: the conv's weight is stored as the ``.pt``
holds it (float16, so no rounding is added) beside a float32 per-output-channel scale
γ/√(σ² + ε) and a float32 bias β − μ·γ/√(σ² + ε). In the graph each weight is cast to float32
and multiplied by its scale; the runtime folds those constants once when it loads the file, so
the forward pass is conv + bias (+ ReLU6 as a clip) and nothing else. Storing the already-folded
weight in float16 instead would round it a second time (measured max |Δp| 1.0e-3 against
torch, against 4e-7 this way).

The graph takes the normalised picture (N, 3, S, S) float32 as ``x`` and gives (N, 24) logits
as ``logits``; the number of pictures is free. Beside the ``.onnx`` lies its metadata as JSON
(same name, ``.json``: format, number of classes, width multiplier, input size, normalisation,
class angles, temperature, the source file's SHA-256), also stored in the model's
``metadata_props`` for other ONNX tools. Its speed: ``benchmarks/bench_view.py --speed``.
"""
from __future__ import annotations

import functools
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from carbody.errors import ViewError
from carbody.view.ends import END_LOOK_KEY
from carbody.view.labels import MIRROR_PERMUTATION, N_CLASSES

#: The exported network shipped with the package (written from ``view_mobilenetv2.pt``).
SHIPPED_ONNX = Path(__file__).resolve().parent / "weights" / "view_mobilenetv2.onnx"

#: The ``format`` field of the metadata this module writes and reads.
ONNX_FORMAT = "carbody-view-mobilenetv2-onnx/1"

#: The ONNX operator set the exported graph uses (Cast, Mul, Conv, Clip, Add, pooling, Gemm).
OPSET = 13


def meta_path(onnx_path: str | Path) -> Path:
    """The JSON metadata file beside an exported ``.onnx``."""
    return Path(onnx_path).with_suffix(".json")


# ------------------------------------------------------------------------------------- export

def export_weights(pt_path: str | Path, onnx_path: str | Path) -> dict:
    """Write the ``.onnx`` (and its ``.json`` metadata) of a ``.pt`` view-classifier weights
    file, BatchNorms folded.

    Needs torch and the ``onnx`` package (training or packaging time, ``pip install .[dev]``).
    The graph is read off the torch network built from the file, so the strides, groups and
    skips are the ones it runs.

    Returns:
        The metadata dict written.

    Raises:
        ViewError: not a view-classifier weights file, or no ``onnx`` package.
    """
    import torch
    from torch import nn

    from carbody.view.network import build_mobilenet_v2

    try:
        from onnx import TensorProto, helper, numpy_helper
    except ImportError:
        raise ViewError("exporting the view classifier needs the onnx package (pip install onnx)") from None
    pt_path, onnx_path = Path(pt_path), Path(onnx_path)
    try:
        payload = torch.load(pt_path, map_location="cpu", weights_only=True)
        num_classes = int(payload["num_classes"])
        width_mult = float(payload.get("width_mult", 1.0))
        model = build_mobilenet_v2(num_classes, width_mult=width_mult)
        model.load_state_dict(payload["state_dict"])   # keeps the file's float16 values
    except Exception as exc:  # a corrupt file can fail in many ways inside torch
        raise ViewError(f"{pt_path}: not a view-classifier weights file ({type(exc).__name__})") from None
    model.eval()

    nodes, inits = [], []
    state = {"x": "x", "saved": None, "i": 0}

    def constant(name: str, array: np.ndarray) -> str:
        inits.append(numpy_helper.from_array(np.ascontiguousarray(array), name))
        return name

    def add(conv: nn.Conv2d, bn: nn.BatchNorm2d, relu6: bool, residual: str | None = None) -> None:
        i, x = state["i"], state["x"]
        state["i"] += 1
        if residual == "save":
            state["saved"] = x
        var = bn.running_var.detach().double().numpy()
        scale = bn.weight.detach().double().numpy() / np.sqrt(var + bn.eps)
        bias = bn.bias.detach().double().numpy() - bn.running_mean.detach().double().numpy() * scale
        w16 = constant(f"w{i:02d}", conv.weight.detach().numpy().astype(np.float16))  # (Cout, Cin/g, k, k)
        s = constant(f"s{i:02d}", scale.astype(np.float32).reshape(-1, 1, 1, 1))
        b = constant(f"b{i:02d}", bias.astype(np.float32))
        k, stride, pad = conv.kernel_size[0], conv.stride[0], conv.padding[0]
        nodes.append(helper.make_node("Cast", [w16], [f"w{i:02d}f"], to=TensorProto.FLOAT))
        nodes.append(helper.make_node("Mul", [f"w{i:02d}f", s], [f"w{i:02d}s"]))
        nodes.append(helper.make_node("Conv", [x, f"w{i:02d}s", b], [f"conv{i:02d}"], kernel_shape=[k, k],
                                      strides=[stride, stride], pads=[pad] * 4, group=conv.groups))
        x = f"conv{i:02d}"
        if relu6:
            nodes.append(helper.make_node("Clip", [x, "zero", "six"], [f"relu{i:02d}"]))
            x = f"relu{i:02d}"
        if residual == "add":
            nodes.append(helper.make_node("Add", [x, state["saved"]], [f"add{i:02d}"]))
            x = f"add{i:02d}"
        state["x"] = x

    constant("zero", np.float32(0.0))
    constant("six", np.float32(6.0))
    for feature in model.features:
        if isinstance(feature, nn.Sequential):                     # stem or last 1×1 conv
            add(feature[0], feature[1], relu6=True)
            continue
        parts = list(feature.conv)
        skip = bool(feature.use_skip)
        for j, part in enumerate(parts[:-2]):
            add(part[0], part[1], relu6=True, residual="save" if skip and j == 0 else None)
        add(parts[-2], parts[-1], relu6=False, residual="add" if skip else None)
    linear = model.classifier[-1]
    nodes += [helper.make_node("GlobalAveragePool", [state["x"]], ["pool"]),
              helper.make_node("Flatten", ["pool"], ["features"]),
              helper.make_node("Cast", [constant("w_linear", linear.weight.detach().numpy().astype(np.float16))],
                               ["w_linear_f"], to=TensorProto.FLOAT),
              helper.make_node("Gemm", ["features", "w_linear_f",
                                        constant("b_linear", linear.bias.detach().float().numpy())],
                               ["logits"], transB=1)]

    size = int(payload.get("input_size", 64))
    meta = {"format": ONNX_FORMAT, "num_classes": num_classes, "width_mult": width_mult, "input_size": size,
            "mean": float(payload.get("mean", 0.5)), "std": float(payload.get("std", 0.25)),
            "classes_deg": list(payload.get("classes_deg", [])), "temperature": float(payload.get("temperature", 1.0)),
            "source": pt_path.name, "source_sha256": hashlib.sha256(pt_path.read_bytes()).hexdigest()}
    if payload.get(END_LOOK_KEY):
        meta[END_LOOK_KEY] = payload[END_LOOK_KEY]
    graph = helper.make_graph(
        nodes, "carbody_view_mobilenetv2",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["N", 3, size, size])],
        [helper.make_tensor_value_info("logits", TensorProto.FLOAT, ["N", num_classes])], inits)
    model_proto = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)], producer_name="carbody")
    helper.set_model_props(model_proto, {"carbody_meta": json.dumps(meta)})
    onnx_path.write_bytes(model_proto.SerializeToString())
    meta_path(onnx_path).write_text(json.dumps(meta, indent=1) + "\n")
    return meta


# ------------------------------------------------------------------------------------- forward

@dataclass
class OnnxClassifier:
    """The exported MobileNetV2, run by ONNX Runtime.

    Attributes:
        session: the ``onnxruntime.InferenceSession`` of the ``.onnx`` (its ``run`` may be called
            from several threads at once).
        meta: the metadata beside it (``num_classes``, ``input_size``, ``mean``, ``std``, ...).
    """

    session: object
    meta: dict

    @classmethod
    def from_file(cls, path: str | Path, threads: int = 1) -> "OnnxClassifier":
        """The network of an ``.onnx`` written by :func:`export_weights` (and its ``.json``),
        run on ``threads`` threads.

        Raises:
            ViewError: not such a file, or its metadata missing.
        """
        onnxruntime = onnxruntime_module()
        path = Path(path)
        try:
            meta = json.loads(meta_path(path).read_text())
            if meta.get("format") != ONNX_FORMAT:
                raise ValueError(meta.get("format"))
            options = onnxruntime.SessionOptions()
            options.intra_op_num_threads = max(1, int(threads))
            options.inter_op_num_threads = 1
            options.log_severity_level = 3          # errors only: no warnings on stderr
            session = onnxruntime.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        except Exception as exc:  # missing metadata, truncated or foreign file
            raise ViewError(f"{path}: not an exported view classifier with its .json beside it "
                            f"({type(exc).__name__})") from None
        return cls(session, meta)

    def network_input(self, images: np.ndarray) -> np.ndarray:
        """(B, 3, S, S) float32 network input from (B, S, S, 3) uint8 square pictures:
        (x / 255 − mean) / std, the same values as ``carbody.view.train.to_tensor``."""
        x = np.asarray(images).astype(np.float32) / np.float32(255.0)
        x -= np.float32(self.meta["mean"])
        x /= np.float32(self.meta["std"])
        return np.ascontiguousarray(x.transpose(0, 3, 1, 2))

    def logits(self, x: np.ndarray) -> np.ndarray:
        """(N, classes) float32 logits of an (N, 3, S, S) float32 batch (already normalised)."""
        x = np.asarray(x, dtype=np.float32)
        size = int(self.meta["input_size"])
        if x.ndim != 4 or x.shape[1:] != (3, size, size):
            raise ViewError(f"the network takes (N, 3, {size}, {size}) input, not {x.shape}")
        (out,) = self.session.run(["logits"], {"x": np.ascontiguousarray(x)})
        return np.asarray(out, dtype=np.float32).reshape(len(x), -1)


def onnxruntime_module():
    """``onnxruntime``, its telemetry off unless the user has set ``ORT_DISABLE_TELEMETRY`` (ONNX
    Runtime's Linux builds otherwise keep a device ID under ``~/.cache`` and send usage events;
    the variable must be set before its first session)."""
    os.environ.setdefault("ORT_DISABLE_TELEMETRY", "1")
    import onnxruntime

    return onnxruntime


def softmax(logits: np.ndarray) -> np.ndarray:
    """Row-wise softmax of (N, K) logits."""
    z = np.exp(logits - logits.max(axis=1, keepdims=True))
    return z / z.sum(axis=1, keepdims=True)


@functools.lru_cache(maxsize=4)
def _load(path_text: str, mtime_ns: int, threads: int) -> OnnxClassifier:  # mtime_ns: cache key only
    net = OnnxClassifier.from_file(path_text, threads)
    if int(net.meta["num_classes"]) != N_CLASSES:
        raise ViewError(f"{path_text}: has {net.meta['num_classes']} classes, expected {N_CLASSES}")
    return net


def load_onnx_classifier(onnx_path: str | Path | None = None) -> OnnxClassifier:
    """The network of an ``.onnx`` (default: the shipped one), read once per file, process and
    thread count (and again when the file changes). It runs on as many threads as OpenCV is set
    to (``cv2.getNumThreads()``: the cores by default, 1 in a batch worker), one setting for the
    process's picture work.

    Raises:
        ViewError: missing or bad file, or not 24 classes.
    """
    import cv2

    from carbody.inputs import MAX_WEIGHTS_BYTES, input_file

    path = input_file(Path(onnx_path) if onnx_path else SHIPPED_ONNX, "weights file", ViewError, MAX_WEIGHTS_BYTES)
    return _load(str(path), path.stat().st_mtime_ns, max(1, cv2.getNumThreads()))


def probabilities(images: np.ndarray, onnx_path: str | Path | None = None,
                  mirror_average: bool = True, temperature: float | None = None) -> np.ndarray:
    """(B, 24) class probabilities of (B, S, S, 3) uint8 square pictures (from
    ``carbody.view.train.to_square_input``), as ``carbody.view.predict.predict_probabilities``
    gives them (float32) but through the exported network: with ``mirror_average``, one pass over
    the pictures and their mirror images, the mirror's classes mapped back and the two averaged.
    ``temperature`` divides the logits (None: the calibrated one the weights carry, else 1)."""
    net = load_onnx_classifier(onnx_path)
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

def onnx_weights_for(weights: str | Path | None) -> Path | None:
    """The ``.onnx`` that ``predict_probabilities(..., weights)`` can run instead of torch, or
    None (a ``.pt`` file: torch). ``weights`` None is the shipped ``.pt``, whose export
    :data:`SHIPPED_ONNX` is (tests/test_onnx_net.py checks they match)."""
    if weights is None:
        return SHIPPED_ONNX if SHIPPED_ONNX.is_file() else None
    return Path(weights) if Path(weights).suffix == ".onnx" else None
