"""Calibrated probabilities: one temperature T fitted on renders of held-out cars.

A network trained with cross-entropy is over-confident on pictures unlike its training set;
dividing its logits by T > 1 (Guo et al., "On Calibration of Modern Neural Networks", 2017)
keeps the ranking of the classes and makes the reported probability mean what it says. T is
fitted by minimising the negative log-likelihood of the validation split of a rendered data set
(the cars not trained on), with the mirror averaging :func:`carbody.view.predict.predict_view`
does, and stored in the weights file (``temperature``). Real photos only check it
(``benchmarks/bench_view.py --real`` prints a reliability table); nothing is fitted on them.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from carbody.errors import ViewError
from carbody.view.labels import MIRROR_PERMUTATION

#: Temperatures searched, as log10 T bounds.
LOG10_T_RANGE = (-1.0, 1.5)


def mirrored_probabilities(logits: np.ndarray, mirror_logits: np.ndarray | None, temperature: float) -> np.ndarray:
    """(B, K) probabilities as predict_view computes them: softmax(logits / T), averaged with the
    mirror image's (classes permuted back) when ``mirror_logits`` is given."""
    def softmax(z):
        z = z / temperature
        z = z - z.max(1, keepdims=True)
        e = np.exp(z)
        return e / e.sum(1, keepdims=True)

    p = softmax(np.asarray(logits, dtype=np.float64))
    if mirror_logits is not None:
        p = (p + softmax(np.asarray(mirror_logits, dtype=np.float64))[:, MIRROR_PERMUTATION]) / 2
    return p


def fit_temperature(logits: np.ndarray, labels: np.ndarray, mirror_logits: np.ndarray | None = None) -> float:
    """The T > 0 minimising the mean negative log-likelihood of ``labels`` (B,) under
    :func:`mirrored_probabilities`.

    Raises:
        ViewError: no samples, or shapes that do not match.
    """
    from scipy.optimize import minimize_scalar

    logits = np.asarray(logits, dtype=np.float64)
    labels = np.asarray(labels, dtype=np.int64)
    if logits.ndim != 2 or len(logits) == 0 or len(labels) != len(logits):
        raise ViewError(f"temperature fit needs (B, K) logits and (B,) labels, got {logits.shape} and {labels.shape}")

    def nll(log10_t: float) -> float:
        p = mirrored_probabilities(logits, mirror_logits, 10.0 ** log10_t)
        return float(-np.log(np.maximum(p[np.arange(len(labels)), labels], 1e-12)).mean())

    res = minimize_scalar(nll, bounds=LOG10_T_RANGE, method="bounded", options={"xatol": 1e-4})
    return float(10.0 ** res.x)


def expected_calibration_error(probs: np.ndarray, labels: np.ndarray, bins: int = 10) -> float:
    """ECE of the top class: Σ_bins (share of samples) · |mean confidence − accuracy|."""
    conf, hit = probs.max(1), probs.argmax(1) == labels
    edges = np.linspace(0, 1, bins + 1)
    ece = 0.0
    for lo, hi in zip(edges[:-1], edges[1:]):
        m = (conf > lo) & (conf <= hi)
        if m.any():
            ece += m.mean() * abs(conf[m].mean() - hit[m].mean())
    return float(ece)


def network_logits(model, x: np.ndarray, batch_size: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """(logits, mirror-image logits), each (B, K), of (B, H, W, 3) uint8 network inputs."""
    import torch

    from carbody.view.train import to_tensor

    model.eval()
    out, mirror = [], []
    with torch.inference_mode():
        for i in range(0, len(x), batch_size):
            xb = x[i:i + batch_size]
            out.append(model(to_tensor(xb)).numpy())
            mirror.append(model(to_tensor(xb[:, :, ::-1])).numpy())
    return np.concatenate(out), np.concatenate(mirror)


def calibrate_weights(weights: str | Path, dataset_dir, progress: bool = True) -> dict:
    """Fit the temperature on a rendered data set's images of the cars held out from training
    (named in the weights; else the data set's validation split) and store it in ``weights``.
    ``dataset_dir``: a folder, or a list of folders (:func:`carbody.view.dataset.read_datasets`).

    Returns:
        {"temperature", "images", "nll_before", "nll_after", "ece_before", "ece_after"} (top class,
        with mirror averaging).

    Raises:
        ViewError: bad weights or data set.
    """
    import os

    import torch

    from carbody.view.dataset import dataset_folders, read_datasets
    from carbody.view.predict import load_classifier
    from carbody.view.train import INPUT_SIZE, load_images

    weights = Path(weights)
    model, meta = load_classifier(str(weights))
    held_out = set(meta.get("dataset", {}).get("validation_templates") or [])
    rows = read_datasets(dataset_dir)
    folders = dataset_folders(dataset_dir)
    # the cars the weights never saw; the data set's own validation split when they name none
    rows = [r for r in rows if r.get("template") in held_out] if held_out else [r for r in rows if r["split"] == "val"]
    if not rows:
        raise ViewError(f"{', '.join(map(str, folders))}: no images of cars held out from training to calibrate on")
    x = load_images(folders[0], rows, progress, int(meta.get("input_size", INPUT_SIZE)))
    y = np.array([r["class_index"] for r in rows], dtype=np.int64)
    logits, mirror = network_logits(model, x)
    t = fit_temperature(logits, y, mirror)
    before, after = mirrored_probabilities(logits, mirror, 1.0), mirrored_probabilities(logits, mirror, t)
    nll = lambda p: float(-np.log(np.maximum(p[np.arange(len(y)), y], 1e-12)).mean())  # noqa: E731
    report = {"temperature": t, "images": len(rows), "nll_before": nll(before), "nll_after": nll(after),
              "ece_before": expected_calibration_error(before, y), "ece_after": expected_calibration_error(after, y)}
    payload = torch.load(weights, map_location="cpu", weights_only=True)
    payload["temperature"] = t
    payload["calibration"] = {k: v for k, v in report.items() if k != "temperature"} | {
        "dataset": ", ".join(str(d) for d in folders)}
    tmp = weights.with_name(f".{weights.name}.{os.getpid()}.tmp")
    torch.save(payload, tmp)
    os.replace(tmp, weights)
    return report
