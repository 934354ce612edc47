"""The numpy view classifier: the exported weights give torch's probabilities (|Δp| < 1e-4, same
top class) on real pictures and noise, without importing torch. (Its speed is measured by
``benchmarks/bench_view.py --speed``, not here.)"""
from __future__ import annotations

import hashlib
import json
import subprocess
import sys

import numpy as np
import pytest

from carbody.errors import ViewError
from carbody.view.numpy_net import (SHIPPED_NPZ, NumpyMobileNetV2, export_weights, load_numpy_classifier,
                                    numpy_weights_for, probabilities, softmax)
from carbody.view.predict import SHIPPED_WEIGHTS, read_image
from tests.conftest import REPO

pytestmark = pytest.mark.skipif(not SHIPPED_WEIGHTS.is_file(), reason="no shipped weights in the package")


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """(path, meta) of the shipped .pt exported to a temporary .npz."""
    pytest.importorskip("torch")
    path = tmp_path_factory.mktemp("npz") / "view.npz"
    return path, export_weights(SHIPPED_WEIGHTS, path)


@pytest.fixture(scope="module")
def square_inputs():
    """(8, n, n, 3) uint8: the example photo, its front half, two docs figures, a flat grey
    picture and three noise pictures, each padded and resized as the shipped classifier reads
    them (n its input size)."""
    from carbody.view.train import to_square_input

    size = load_numpy_classifier().meta["input_size"]

    car = read_image(REPO / "examples" / "car.png")
    rng = np.random.default_rng(0)
    pictures = [car, car[:, : car.shape[1] // 2], read_image(REPO / "docs" / "body.png"),
                read_image(REPO / "docs" / "overlay.png"), np.full((90, 120, 3), 128, np.uint8)]
    pictures += [rng.integers(0, 256, (64 + 16 * i, 80, 3), dtype=np.uint8) for i in range(3)]
    return np.stack([to_square_input(p, size) for p in pictures])


def torch_probabilities(x: np.ndarray) -> np.ndarray:
    """(B, 24) softmax of the torch network (shipped weights) on (B, n, n, 3) uint8 inputs."""
    import torch

    from carbody.view.predict import load_classifier
    from carbody.view.train import to_tensor

    model, _ = load_classifier()
    with torch.inference_mode():
        return torch.softmax(model(to_tensor(x)), 1).numpy()


def test_export_folds_every_batchnorm_into_a_compact_file(exported):
    path, meta = exported
    layers = meta["layers"]
    assert len(layers) == 1 + 2 + 16 * 3 + 1 + 1            # stem, 17 blocks, last 1×1, linear
    assert sum(layer["residual"] == "add" for layer in layers) == 10
    assert sum(layer["residual"] == "save" for layer in layers) == 10
    assert [layer["op"] for layer in layers[:3]] == ["conv3x3", "depthwise", "pointwise"]
    assert (meta["num_classes"], meta["width_mult"], meta["input_size"], meta["mean"], meta["std"]) == \
        (24, 1.0, 96, 0.5, 0.25)
    with np.load(path) as f:
        assert not any("running" in k or "num_batches" in k for k in f.files)
        assert {f[k].dtype for k in f.files if k.startswith("w")} == {np.dtype(np.float16)}
        linear = f"s{len(layers) - 1:02d}"                      # the linear layer's unit scale
        n_stored = sum(f[k].size for k in f.files if k != "meta" and k != linear)
    assert n_stored == 2_254_616                             # conv w, BN γ, β as s, b; linear w, b
    assert path.stat().st_size < 5_000_000


def test_numpy_input_is_torch_input(exported, square_inputs):
    pytest.importorskip("torch")
    from carbody.view.train import to_tensor

    net = NumpyMobileNetV2.from_npz(exported[0])
    assert np.array_equal(net.network_input(square_inputs), to_tensor(square_inputs).numpy().transpose(0, 2, 3, 1))


def test_numpy_logits_give_torch_probabilities(exported, square_inputs):
    net = NumpyMobileNetV2.from_npz(exported[0])
    x = np.concatenate([square_inputs, square_inputs[:, :, ::-1]])
    p_numpy = softmax(net.logits(net.network_input(x)))
    p_torch = torch_probabilities(x)
    assert np.abs(p_numpy - p_torch).max() < 1e-4
    assert np.array_equal(p_numpy.argmax(1), p_torch.argmax(1))


def test_channels_first_and_channels_last_batches_give_the_same_logits(exported, square_inputs):
    net = NumpyMobileNetV2.from_npz(exported[0])
    x = net.network_input(square_inputs[:2])
    assert np.array_equal(net.logits(x), net.logits(np.ascontiguousarray(x.transpose(0, 3, 1, 2))))


def test_mirror_averaged_probabilities_match_predict_probabilities(exported, square_inputs):
    pytest.importorskip("torch")
    from carbody.view.predict import predict_probabilities

    car = REPO / "examples" / "car.png"
    p_torch = predict_probabilities([car])
    p_numpy = probabilities(square_inputs[:1], exported[0])
    assert np.abs(p_numpy - p_torch).max() < 1e-4 and p_numpy.argmax() == p_torch.argmax()
    assert p_numpy.dtype == p_torch.dtype == np.float32 and np.allclose(p_numpy.sum(1), 1.0)
    single = probabilities(square_inputs[:1], exported[0], mirror_average=False)
    assert np.abs(single - predict_probabilities([car], mirror_average=False)).max() < 1e-4


def test_shipped_npz_is_the_export_of_the_shipped_pt(exported):
    """Fails when the .pt changes without the .npz: regenerate with export_weights."""
    with np.load(SHIPPED_NPZ) as shipped, np.load(exported[0]) as fresh:
        assert json.loads(str(shipped["meta"]))["source_sha256"] == \
            hashlib.sha256(SHIPPED_WEIGHTS.read_bytes()).hexdigest()
        assert shipped.files == fresh.files
        assert all(np.array_equal(shipped[k], fresh[k]) for k in shipped.files if k != "meta")
    assert SHIPPED_NPZ.stat().st_size + SHIPPED_WEIGHTS.stat().st_size < 10_000_000


def test_the_numpy_classifier_never_imports_torch():
    code = ("import sys, numpy as np\n"
            "from carbody.view.numpy_net import probabilities\n"
            "p = probabilities(np.zeros((1, 64, 64, 3), np.uint8))\n"
            "assert p.shape == (1, 24), p.shape\n"
            "print('torch' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, check=True)
    assert out.stdout.strip() == "False"


def test_bad_npz_and_bad_input_are_refused(tmp_path, exported):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(ViewError, match="not a numpy view-classifier"):
        NumpyMobileNetV2.from_npz(bad)
    with pytest.raises(ViewError, match="no such"):
        load_numpy_classifier(tmp_path / "missing.npz")
    with pytest.raises(ViewError, match="square pictures"):
        probabilities(np.zeros((64, 64, 3), np.uint8), exported[0])


def test_the_shipped_and_npz_weights_run_in_numpy_and_a_pt_file_in_torch(tmp_path):
    assert numpy_weights_for(None) == SHIPPED_NPZ
    assert numpy_weights_for(tmp_path / "mine.npz") == tmp_path / "mine.npz"
    assert numpy_weights_for(str(tmp_path / "mine.pt")) is None
