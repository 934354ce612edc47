"""The exported view classifier: ONNX Runtime runs the shipped weights to torch's
probabilities (|Δp| < 1e-4, same top class) on real pictures and noise, without importing torch.
(Its speed is measured by ``benchmarks/bench_view.py --speed``, not here.)"""
from __future__ import annotations

import hashlib
import json
import subprocess
import sys

import numpy as np
import pytest

from carbody.errors import ViewError
from carbody.view.onnx_net import (SHIPPED_ONNX, OnnxClassifier, export_weights, load_onnx_classifier, meta_path,
                                   onnx_weights_for, probabilities, softmax)
from carbody.view.predict import SHIPPED_WEIGHTS, read_image
from tests.conftest import REPO

pytestmark = pytest.mark.skipif(not SHIPPED_WEIGHTS.is_file(), reason="no shipped weights in the package")


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """(path, meta) of the shipped .pt exported to a temporary .onnx."""
    pytest.importorskip("torch")
    pytest.importorskip("onnx")
    path = tmp_path_factory.mktemp("onnx") / "view.onnx"
    return path, export_weights(SHIPPED_WEIGHTS, path)


@pytest.fixture(scope="module")
def square_inputs():
    """(8, n, n, 3) uint8: the example photo, its front half, two docs figures, a flat grey
    picture and three noise pictures, each padded and resized as the shipped classifier reads
    them (n its input size)."""
    from carbody.view.train import to_square_input

    size = load_onnx_classifier().meta["input_size"]

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
    import onnx

    path, meta = exported
    model = onnx.load(path)
    onnx.checker.check_model(model)
    ops = [node.op_type for node in model.graph.node]
    assert ops.count("Conv") == 1 + 2 + 16 * 3 + 1             # stem, 17 blocks, last 1×1
    assert ops.count("Add") == 10 and ops.count("Clip") == 1 + 1 + 16 * 2 + 1
    assert "BatchNormalization" not in ops
    groups = [next(a.i for a in n.attribute if a.name == "group") for n in model.graph.node if n.op_type == "Conv"]
    assert groups[:3] == [1, 32, 1]                          # stem, depthwise, pointwise
    assert (meta["num_classes"], meta["width_mult"], meta["mean"], meta["std"]) == (24, 1.0, 0.5, 0.25)
    assert meta["input_size"] == json.loads(meta_path(SHIPPED_ONNX).read_text())["input_size"] >= 64
    inits = {t.name: t for t in model.graph.initializer}
    assert {t.data_type for name, t in inits.items() if name.startswith("w")} == {onnx.TensorProto.FLOAT16}
    n_stored = sum(int(np.prod(t.dims)) for name, t in inits.items() if name not in ("zero", "six"))
    assert n_stored == 2_254_616                             # conv w, BN γ, β as s, b; linear w, b
    assert path.stat().st_size < 5_000_000
    assert json.loads(meta_path(path).read_text()) == meta
    assert json.loads({p.key: p.value for p in model.metadata_props}["carbody_meta"]) == meta


def test_network_input_is_torch_input(exported, square_inputs):
    pytest.importorskip("torch")
    from carbody.view.train import to_tensor

    net = OnnxClassifier.from_file(exported[0])
    assert np.array_equal(net.network_input(square_inputs), to_tensor(square_inputs).numpy())


def test_logits_give_torch_probabilities(exported, square_inputs):
    net = OnnxClassifier.from_file(exported[0])
    x = np.concatenate([square_inputs, square_inputs[:, :, ::-1]])
    p_onnx = softmax(net.logits(net.network_input(x)))
    p_torch = torch_probabilities(x)
    assert np.abs(p_onnx - p_torch).max() < 1e-4
    assert np.array_equal(p_onnx.argmax(1), p_torch.argmax(1))


def test_one_picture_at_a_time_gives_the_batch_logits(exported, square_inputs):
    net = OnnxClassifier.from_file(exported[0])
    x = net.network_input(square_inputs[:3])
    one_by_one = np.concatenate([net.logits(x[i:i + 1]) for i in range(3)])
    assert np.abs(net.logits(x) - one_by_one).max() < 1e-4


def test_mirror_averaged_probabilities_match_predict_probabilities(exported, square_inputs):
    pytest.importorskip("torch")
    from carbody.view.predict import predict_probabilities

    car = REPO / "examples" / "car.png"
    p_torch = predict_probabilities([car], SHIPPED_WEIGHTS)
    p_onnx = probabilities(square_inputs[:1], exported[0])
    assert np.abs(p_onnx - p_torch).max() < 1e-4 and p_onnx.argmax() == p_torch.argmax()
    assert p_onnx.dtype == p_torch.dtype == np.float32 and np.allclose(p_onnx.sum(1), 1.0)
    single = probabilities(square_inputs[:1], exported[0], mirror_average=False)
    assert np.abs(single - predict_probabilities([car], SHIPPED_WEIGHTS, mirror_average=False)).max() < 1e-4


def test_shipped_onnx_is_the_export_of_the_shipped_pt(exported):
    """Fails when the .pt changes without the .onnx: regenerate with export_weights."""
    assert json.loads(meta_path(SHIPPED_ONNX).read_text())["source_sha256"] == \
        hashlib.sha256(SHIPPED_WEIGHTS.read_bytes()).hexdigest()
    assert SHIPPED_ONNX.read_bytes() == exported[0].read_bytes()
    assert meta_path(SHIPPED_ONNX).read_text() == meta_path(exported[0]).read_text()
    assert SHIPPED_ONNX.stat().st_size + SHIPPED_WEIGHTS.stat().st_size < 10_000_000


def test_the_exported_classifier_never_imports_torch_or_onnx():
    code = ("import sys, numpy as np\n"
            "from carbody.view.onnx_net import load_onnx_classifier, probabilities\n"
            "s = load_onnx_classifier().meta['input_size']\n"
            "p = probabilities(np.zeros((1, s, s, 3), np.uint8))\n"
            "assert p.shape == (1, 24), p.shape\n"
            "print('torch' in sys.modules, 'onnx' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, check=True)
    assert out.stdout.strip() == "False False"


def test_bad_files_and_bad_input_are_refused(tmp_path, exported):
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not a model")
    meta_path(bad).write_text(meta_path(exported[0]).read_text())
    with pytest.raises(ViewError, match="not an exported view classifier"):
        OnnxClassifier.from_file(bad)
    alone = tmp_path / "alone.onnx"
    alone.write_bytes(exported[0].read_bytes())            # its .json missing
    with pytest.raises(ViewError, match="not an exported view classifier"):
        OnnxClassifier.from_file(alone)
    with pytest.raises(ViewError, match="no such"):
        load_onnx_classifier(tmp_path / "missing.onnx")
    with pytest.raises(ViewError, match="square pictures"):
        probabilities(np.zeros((64, 64, 3), np.uint8), exported[0])
    size = exported[1]["input_size"]
    with pytest.raises(ViewError, match=rf"\(N, 3, {size}, {size}\)"):
        OnnxClassifier.from_file(exported[0]).logits(np.zeros((1, 3, size // 2, size // 2), np.float32))


def test_the_shipped_and_onnx_weights_run_in_opencv_and_a_pt_file_in_torch(tmp_path):
    assert onnx_weights_for(None) == SHIPPED_ONNX
    assert onnx_weights_for(tmp_path / "mine.onnx") == tmp_path / "mine.onnx"
    assert onnx_weights_for(str(tmp_path / "mine.pt")) is None


def test_the_network_runs_on_as_many_threads_as_opencv_is_set_to():
    """One knob for the process's picture work: a batch worker sets OpenCV to one thread before
    it loads the classifier (carbody.cluster.warm_up), and the network then runs on one."""
    import cv2

    before = cv2.getNumThreads()
    try:
        cv2.setNumThreads(1)
        one = load_onnx_classifier()
        cv2.setNumThreads(2)
        two = load_onnx_classifier()
        assert one.session.get_session_options().intra_op_num_threads == 1
        assert two.session.get_session_options().intra_op_num_threads == 2
        x = one.network_input(np.zeros((1, one.meta["input_size"], one.meta["input_size"], 3), np.uint8))
        assert np.allclose(one.logits(x), two.logits(x), atol=1e-4)
    finally:
        cv2.setNumThreads(before)


def test_the_network_runs_without_writing_under_home_or_a_word_on_stderr(tmp_path):
    """ONNX Runtime's Linux builds keep a telemetry device ID under ~/.cache unless told not to:
    carbody tells it, so a run leaves the user's home as it was and says nothing on stderr."""
    import os

    home = tmp_path / "home"
    home.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("ORT_DISABLE_TELEMETRY", "XDG_CACHE_HOME")}
    env["HOME"] = str(home)
    proc = subprocess.run([sys.executable, "-c",
                           "import numpy as np\n"
                           "from carbody.view.onnx_net import load_onnx_classifier, probabilities\n"
                           "n = load_onnx_classifier().meta['input_size']\n"
                           "print(probabilities(np.zeros((1, n, n, 3), np.uint8)).shape)"],
                          capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    assert proc.returncode == 0 and proc.stdout.strip() == "(1, 24)" and proc.stderr == "", proc.stderr
    assert list(home.rglob("*")) == []
