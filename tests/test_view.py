"""The view classifier: MobileNetV2 as published, labels, picture input, data set, training, CLI."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from carbody.errors import ImageError, ViewError
from carbody.view.ends import END_LOOK_KEY
from carbody.view.labels import (CLASS_ANGLES_DEG, MIRROR_PERMUTATION, N_CLASSES, angular_difference,
                                 class_of, continuous_estimate, mirror_class)
from tests.conftest import run_cli

torch = pytest.importorskip("torch")


# ------------------------------------------------------------------------------------- network

def n_params(model) -> int:
    return sum(p.numel() for p in model.parameters())


def test_mobilenet_v2_has_the_reference_parameter_count():
    from carbody.view.network import build_mobilenet_v2, expected_parameter_count

    assert n_params(build_mobilenet_v2(1000)) == 3_504_872          # torchvision mobilenet_v2()
    assert n_params(build_mobilenet_v2(N_CLASSES)) == expected_parameter_count(N_CLASSES) == 2_254_616


def test_mobilenet_v2_structure_inverted_residuals_and_linear_bottlenecks():
    from torch import nn

    from carbody.view.network import build_mobilenet_v2

    model = build_mobilenet_v2(N_CLASSES)
    blocks = [m for m in model.modules() if type(m).__name__ == "InvertedResidual"]
    assert len(blocks) == 17                                        # 1 + 2 + 3 + 4 + 3 + 3 + 1
    assert sum(b.use_skip for b in blocks) == 10                    # stride 1 and same width
    for b in blocks:                                                # projection is linear: ends in BN
        assert isinstance(b.conv[-1], nn.BatchNorm2d) and isinstance(b.conv[-2], nn.Conv2d)
        assert not any(isinstance(m, nn.ReLU6) for m in list(b.conv)[-2:])
    model.eval()
    with torch.no_grad():
        out = model(torch.zeros(2, 3, 64, 64))
    assert out.shape == (2, N_CLASSES)


def test_width_multiplier_shrinks_the_network():
    from carbody.view.network import build_mobilenet_v2

    assert n_params(build_mobilenet_v2(N_CLASSES, width_mult=0.5)) < 0.6 * n_params(build_mobilenet_v2(N_CLASSES))


# ------------------------------------------------------------------------------------- labels

def test_classes_cover_the_circle_and_mirror():
    assert N_CLASSES == 24 and CLASS_ANGLES_DEG[6] == 90 and CLASS_ANGLES_DEG[18] == 270
    assert class_of(7.4) == 0 and class_of(352.6) == 0 and class_of(-15) == 23 and class_of(100) == 7
    assert mirror_class(class_of(30)) == class_of(330) and mirror_class(0) == 0 and mirror_class(12) == 12
    assert np.array_equal(MIRROR_PERMUTATION[MIRROR_PERMUTATION], np.arange(N_CLASSES))
    assert angular_difference(350, 10) == 20


def test_continuous_estimate_moves_toward_the_runner_up():
    p = np.zeros(N_CLASSES)
    p[2], p[3] = 0.6, 0.4                        # between 30° and 45°, nearer 30°
    assert 30 < continuous_estimate(p) < 37.5
    p = np.zeros(N_CLASSES)
    p[0], p[23] = 0.5, 0.5                       # wraps: halfway between 345° and 0°
    assert angular_difference(continuous_estimate(p), 352.5) < 1e-6
    p = np.zeros(N_CLASSES)
    p[6], p[18] = 0.55, 0.45                     # far-away mass is ignored
    assert continuous_estimate(p) == pytest.approx(90)


# ------------------------------------------------------------------------------------- pictures

def test_read_image_handles_gray_rgba_and_16_bit(tmp_path):
    import cv2

    from carbody.view.predict import read_image

    gray = np.full((40, 50), 100, dtype=np.uint8)
    assert read_image(gray).shape == (40, 50, 3)
    cv2.imwrite(str(tmp_path / "g.png"), gray)
    assert np.all(read_image(tmp_path / "g.png") == 100)
    rgba = np.zeros((40, 50, 4), dtype=np.uint8)
    rgba[..., 0] = 255
    rgba[:, :25, 3] = 255                         # left half opaque red, right half transparent
    cv2.imwrite(str(tmp_path / "a.png"), cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA))
    img = read_image(tmp_path / "a.png")
    assert tuple(img[0, 0]) == (255, 0, 0) and tuple(img[0, 49]) == (255, 255, 255)
    deep = np.full((32, 32, 3), 65535, dtype=np.uint16)
    cv2.imwrite(str(tmp_path / "d.png"), deep)
    assert np.all(read_image(tmp_path / "d.png") == 255)


def test_read_image_refuses_bad_files(tmp_path):
    from carbody.view.predict import read_image

    (tmp_path / "empty.png").write_bytes(b"")
    (tmp_path / "text.png").write_text("not a picture at all")
    with pytest.raises(ImageError, match="empty"):
        read_image(tmp_path / "empty.png")
    with pytest.raises(ImageError, match="not an image"):
        read_image(tmp_path / "text.png")
    with pytest.raises(ImageError, match="no such"):
        read_image(tmp_path / "missing.png")
    with pytest.raises(ImageError, match="too small"):
        read_image(np.zeros((8, 300, 3), dtype=np.uint8))
    with pytest.raises(ImageError, match="empty"):
        read_image(np.zeros((0, 0, 3), dtype=np.uint8))


def test_square_input_keeps_the_aspect_ratio():
    from carbody.view.train import to_square_input

    wide = np.zeros((100, 200, 3), dtype=np.uint8)
    wide[:, :, 1] = 255                           # green everywhere, edges replicated
    wide[40:60, 50:150] = 255
    sq = to_square_input(wide)
    assert sq.shape == (64, 64, 3)
    rows = np.nonzero((sq == 255).all(axis=2).any(axis=1))[0]
    cols = np.nonzero((sq == 255).all(axis=2).any(axis=0))[0]
    assert (np.ptp(cols) + 1) / (np.ptp(rows) + 1) == pytest.approx(5.0, rel=0.25)


def test_random_erasing_fills_one_rectangle_in_about_half_of_the_pictures():
    from carbody.view.train import augment_batch, erase_patches

    rng = np.random.default_rng(0)
    x = np.full((400, 64, 64, 3), 128.0)
    erase_patches(x, rng)
    changed = (x != 128.0).any(axis=3)
    hit = changed.any(axis=(1, 2))
    assert 0.4 < hit.mean() < 0.6
    for m in changed[hit][:50]:                          # one rectangle, 2-20 % of the picture
        rows, cols = np.flatnonzero(m.any(axis=1)), np.flatnonzero(m.any(axis=0))
        box = (np.ptp(rows) + 1) * (np.ptp(cols) + 1)
        assert 0.01 * 64 * 64 <= box <= 0.22 * 64 * 64
        assert m.sum() >= 0.95 * box
    # Off (the default), the batch and the generator's stream are as without the option.
    imgs, labels = np.random.default_rng(1).integers(0, 255, (8, 32, 32, 3)).astype(np.uint8), np.arange(8)
    a, b = np.random.default_rng(2), np.random.default_rng(2)
    assert np.array_equal(augment_batch(imgs, labels, a)[0], augment_batch(imgs, labels, b, erase=False)[0])
    assert a.random() == b.random()


# ------------------------------------------------------------------------------------- data set

def toy_body(wireframe):
    """A stand-in body for tests that do not need carbody.surface: a box for the lower body and
    a smaller glass box toward the rear for the cabin, sized from the wireframe (mm)."""
    import cadquery as cq

    p = wireframe.control_points
    length, half_w = np.ptp(p[:, 1]), p[:, 0].max()
    z0, z1 = p[:, 2].min(), p[:, 2].max()
    belt = z0 + 0.55 * (z1 - z0)
    lower = cq.Workplane().box(2 * half_w, length, belt - z0).translate((0, p[:, 1].min() + length / 2, (z0 + belt) / 2))
    cabin = cq.Workplane().box(1.7 * half_w, 0.45 * length, z1 - belt).translate(
        (0, p[:, 1].min() + 0.6 * length, (belt + z1) / 2))
    return [("door", lower.val()), ("side_window", cabin.val())]


def test_dataset_is_deterministic_and_split_by_car(tmp_path):
    from carbody.view.dataset import read_manifest, render_dataset

    kw = dict(count=30, seed=3, bodies_per_template=2, surface_body=toy_body, progress=False,
              templates=["Toyota Camry XV70", "Volvo V60", "Ford F-150 SuperCrew 5.5 ft", "Mazda MX-5 ND",
                         "Tesla Model 3"])
    render_dataset(tmp_path / "a", **kw)
    render_dataset(tmp_path / "b", **kw)
    rows = read_manifest(tmp_path / "a")
    assert len(rows) == 30
    for r in rows:
        assert (tmp_path / "a" / r["file"]).read_bytes() == (tmp_path / "b" / r["file"]).read_bytes()
    train = {r["template"] for r in rows if r["split"] == "train"}
    val = {r["template"] for r in rows if r["split"] == "val"}
    assert train and val and not train & val
    assert not {r["body"] for r in rows if r["split"] == "train"} & {r["body"] for r in rows if r["split"] == "val"}
    assert any(int(r["mirrored"]) for r in rows) and any(r["class_index"] > 12 for r in rows)
    with pytest.raises(ViewError, match="already holds"):
        render_dataset(tmp_path / "a", **kw)


def test_mirrored_classes_are_flipped_renders(tmp_path):
    """A right-side class image is the left-side render flipped: the nose points right."""
    from carbody.render import Look, Scene, tessellate
    from carbody.templates import load_templates
    from carbody.view.dataset import Shot, Variation, shoot

    _, wf = load_templates()[0]
    faces = toy_body(wf)
    scene = Scene(tessellate(faces), size=(128, 128))
    look = Look(ambient=1, diffuse=0, specular=0, paint=(1, 0, 0), glass=(0, 0, 1))
    kw = dict(elevation_deg=0.0, roll_deg=0.0, distance_lengths=0.0, fill=0.9, offset=(0.0, 0.0),
              background="white", paint=(1, 0, 0))
    left = shoot(scene, Shot(6, 90.0, 90.0, False, **kw), look, 4000.0, np.random.default_rng(0), Variation(colour=False, background=False))
    right = shoot(scene, Shot(18, 270.0, 90.0, True, **kw), look, 4000.0, np.random.default_rng(0), Variation(colour=False, background=False))
    assert np.array_equal(right, left[:, ::-1])
    glass_cols = np.nonzero(((left[..., 2] > 150) & (left[..., 0] < 100)).any(axis=0))[0]
    assert glass_cols.mean() > 64        # cabin toward the rear = right of the picture at 90°


@pytest.fixture(scope="module")
def toy_dataset(tmp_path_factory):
    from carbody.view.dataset import render_dataset

    out = tmp_path_factory.mktemp("toyset")
    render_dataset(out, count=96, seed=0, bodies_per_template=1, surface_body=toy_body, progress=False,
                   templates=["Toyota Camry XV70", "Volvo V60", "Ford F-150 SuperCrew 5.5 ft",
                              "Mazda MX-5 ND", "Honda City e:HEV"])
    return out


def test_short_training_lowers_the_loss(toy_dataset, tmp_path):
    """A few epochs on a few dozen rendered images: the loss falls, weights and Fig. 5 plot written,
    and the weights load back for prediction."""
    from carbody.view.predict import load_classifier, predict_view
    from carbody.view.train import TrainConfig, train_view_classifier

    out = tmp_path / "w.pt"
    hist = train_view_classifier(toy_dataset, out, TrainConfig(epochs=6, batch_size=16, augment=False),
                                 progress=False)
    assert len(hist.train_loss) == 6
    assert min(hist.train_loss[-2:]) < 0.8 * hist.train_loss[0]
    assert out.stat().st_size < 5_000_000 and out.with_suffix(".png").stat().st_size > 5000
    _, meta = load_classifier(str(out))
    assert meta["history"]["train_loss"] == pytest.approx(hist.train_loss)
    img = next((toy_dataset / "images").rglob("*.png"))
    p = predict_view(img, weights=out)
    assert p.probabilities.shape == (N_CLASSES,) and p.probabilities.sum() == pytest.approx(1, abs=1e-5)


def test_an_interrupted_training_resumes_where_it_stopped(toy_dataset, tmp_path, monkeypatch):
    """Stopped after its first epoch and resumed, a run ends with the history of one that ran
    straight through (model, optimiser, schedule and random state all come back). A half-width
    network for speed."""
    import carbody.view.train as train

    cfg = train.TrainConfig(epochs=2, batch_size=16, resume=True, width_mult=0.5)
    straight = train.train_view_classifier(toy_dataset, tmp_path / "a.pt", cfg, progress=False)
    save = train._save_checkpoint

    def save_then_stop(path, model, opt, sched, rng, hist):
        save(path, model, opt, sched, rng, hist)
        if len(hist.train_loss) == 1:
            raise KeyboardInterrupt

    monkeypatch.setattr(train, "_save_checkpoint", save_then_stop)
    with pytest.raises(KeyboardInterrupt):
        train.train_view_classifier(toy_dataset, tmp_path / "b.pt", cfg, progress=False)
    assert (tmp_path / "b.ckpt").exists() and not (tmp_path / "b.pt").exists()
    epochs_run = []

    def save_counting(path, model, opt, sched, rng, hist):
        epochs_run.append(len(hist.train_loss))
        save(path, model, opt, sched, rng, hist)

    monkeypatch.setattr(train, "_save_checkpoint", save_counting)
    resumed = train.train_view_classifier(toy_dataset, tmp_path / "b.pt", cfg, progress=False)
    assert epochs_run == [2]                # only the second epoch ran again, not the run from scratch
    assert resumed.train_loss == pytest.approx(straight.train_loss, rel=1e-5)
    assert resumed.val_acc == pytest.approx(straight.val_acc)
    assert not (tmp_path / "b.ckpt").exists()


def test_two_data_sets_train_together_only_when_they_hold_out_the_same_cars(toy_dataset, tmp_path):
    """Photo-like renders and classic ones, say, rendered apart with the same seed: trained on
    together, every image of both counts once. A set that holds out another car is refused
    before any training, naming the problem."""
    import shutil

    from carbody.view.dataset import read_datasets, read_manifest, render_dataset
    from carbody.view.predict import load_classifier
    from carbody.view.train import TrainConfig, train_view_classifier

    second = tmp_path / "second"
    render_dataset(second, count=48, seed=0, bodies_per_template=1, surface_body=toy_body, progress=False,
                   templates=["Toyota Camry XV70", "Volvo V60", "Ford F-150 SuperCrew 5.5 ft",
                              "Mazda MX-5 ND", "Honda City e:HEV"])
    info = json.loads((second / "dataset.json").read_text())     # as `carbody end-looks` marks its sets
    (second / "dataset.json").write_text(json.dumps(info | {END_LOOK_KEY: {"images": 48}}))
    rows = read_datasets([toy_dataset, second])
    assert len(rows) == len(read_manifest(toy_dataset)) + len(read_manifest(second)) == 96 + 48
    assert all(Path(r["file"]).is_absolute() and Path(r["file"]).is_file() for r in rows)
    out = tmp_path / "w.pt"
    train_view_classifier([toy_dataset, second], out, TrainConfig(epochs=1, batch_size=16, width_mult=0.5,
                                                                  augment=False), progress=False)
    _, meta = load_classifier(str(out))
    assert meta["dataset"]["images"] == 144 and meta["dataset"]["folders"] == [toy_dataset.name, "second"]
    assert meta[END_LOOK_KEY] == {"folders": ["second"]}      # so predict_probabilities takes two looks

    other = tmp_path / "other"
    shutil.copytree(second, other)
    info = json.loads((other / "dataset.json").read_text())
    info["validation_templates"] = ["Mazda MX-5 ND"] if info["validation_templates"] != ["Mazda MX-5 ND"] \
        else ["Volvo V60"]
    (other / "dataset.json").write_text(json.dumps(info))
    with pytest.raises(ViewError, match="hold out different cars"):
        train_view_classifier([toy_dataset, other], tmp_path / "x.pt", TrainConfig(epochs=1))
    assert not (tmp_path / "x.pt").exists()


def test_a_soup_is_the_mean_of_networks_fine_tuned_from_one_start(toy_dataset, tmp_path):
    """Two fine-tunes of one start (seeds 1 and 2) averaged: every weight is their mean, the soup
    loads and classifies, and ``soup-view --calibrate`` fits its temperature. Ingredients that
    are not one network from one start are refused in one line, and nothing is written."""
    from carbody.view.predict import load_classifier, predict_view
    from carbody.view.train import TrainConfig, average_weights, train_view_classifier

    quick = dict(epochs=1, batch_size=16, width_mult=0.5, augment=False)
    start = tmp_path / "start.pt"
    train_view_classifier(toy_dataset, start, TrainConfig(**quick), progress=False)
    tuned = [tmp_path / f"tuned{s}.pt" for s in (1, 2)]
    for s, out in zip((1, 2), tuned):
        train_view_classifier(toy_dataset, out, TrainConfig(**quick, seed=s, init=str(start), lr=1e-3),
                              progress=False)
    a, b = (torch.load(t, weights_only=True)["state_dict"] for t in tuned)
    soup = tmp_path / "soup.pt"
    payload = average_weights(tuned, soup)
    moved = 0
    for k, v in torch.load(soup, weights_only=True)["state_dict"].items():
        if v.is_floating_point():
            assert torch.allclose(v.float(), (a[k].float() + b[k].float()) / 2, atol=2e-3, rtol=2e-3), k
            moved += not torch.equal(a[k], b[k])
    assert moved > 100                       # the two seeds did differ
    assert [i["seed"] for i in payload["soup"]] == [1, 2] and payload["config"]["init"] == str(start)
    p = predict_view(next((toy_dataset / "images").rglob("*.png")), weights=soup)
    assert p.probabilities.sum() == pytest.approx(1, abs=1e-5)

    with pytest.raises(ViewError, match="at least two"):
        average_weights(tuned[:1], tmp_path / "x.pt")
    with pytest.raises(ViewError, match="one of the weights averaged"):
        average_weights(tuned, tuned[1])
    with pytest.raises(ViewError, match="from scratch"):
        average_weights([start, tuned[0]], tmp_path / "x.pt")
    other = tmp_path / "other.pt"                   # fine-tuned from another start
    train_view_classifier(toy_dataset, other, TrainConfig(**quick, init=str(tuned[0])), progress=False)
    with pytest.raises(ViewError, match="one start"):
        average_weights([tuned[0], other], tmp_path / "x.pt")
    assert END_LOOK_KEY not in payload                # no ingredient learnt the near end's looks
    torch.save(torch.load(tuned[1], weights_only=True) | {END_LOOK_KEY: {"folders": ["ends"]}}, tmp_path / "ends.pt")
    with pytest.raises(ViewError, match="near end's looks"):
        average_weights([tuned[0], tmp_path / "ends.pt"], tmp_path / "x.pt")
    assert not (tmp_path / "x.pt").exists()
    bigger = torch.load(tuned[1], weights_only=True) | {"input_size": 96}
    torch.save(bigger, tmp_path / "bigger.pt")
    with pytest.raises(ViewError, match="input_size 96 differs"):
        average_weights([tuned[0], tmp_path / "bigger.pt"], tmp_path / "x.pt")
    (tmp_path / "junk.pt").write_text("not weights")
    with pytest.raises(ViewError, match="not a view classifier"):
        average_weights([tuned[0], tmp_path / "junk.pt"], tmp_path / "x.pt")
    assert not (tmp_path / "x.pt").exists()

    proc = run_cli("soup-view", *map(str, tuned), "-o", str(tmp_path / "cal.pt"), "--calibrate", str(toy_dataset))
    assert proc.returncode == 0, proc.stderr
    _, meta = load_classifier(str(tmp_path / "cal.pt"))
    assert meta["temperature"] != 1.0 and meta["calibration"]["images"] > 0 and len(meta["soup"]) == 2
    proc = run_cli("soup-view", *map(str, tuned), "-o", str(tmp_path / "bad.pt"), "--calibrate",
                   str(tmp_path / "no such set"))
    assert proc.returncode == 2 and proc.stderr.strip().count("\n") == 0, proc.stderr
    assert not list(tmp_path.glob("*bad*"))
    before = tuned[0].read_bytes()
    proc = run_cli("soup-view", *map(str, tuned), "-o", str(tuned[0]), "--calibrate", str(toy_dataset))
    assert proc.returncode == 2 and "one of the weights averaged" in proc.stderr
    assert tuned[0].read_bytes() == before


def test_training_refuses_a_bad_dataset(tmp_path):
    from carbody.view.train import train_view_classifier

    with pytest.raises(ViewError, match="no such"):
        train_view_classifier(tmp_path / "nothing", tmp_path / "w.pt")
    (tmp_path / "set" / "banana").mkdir(parents=True)
    with pytest.raises(ViewError, match="angle"):
        train_view_classifier(tmp_path / "set", tmp_path / "w.pt")


# ------------------------------------------------------------------------------------- CLI

def test_view_cli_refuses_bad_input_in_one_line(tmp_path):
    (tmp_path / "bad.jpg").write_text("hello")
    proc = run_cli("view", str(tmp_path / "bad.jpg"))
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "not an image" in proc.stderr
    proc = run_cli("train-view", str(tmp_path / "nothing"), "-o", str(tmp_path / "w.pt"))
    assert proc.returncode == 2 and "no such" in proc.stderr


def test_rendered_bodies_have_wheels_lamps_and_grille_in_place(library, templates):
    """The data set's bodies: our surfaced shell plus wheels at the wheel centres, head lights and
    grille on the front face, tail lights on the tail, each on both sides."""
    pytest.importorskip("carbody.surface")
    from carbody.view.dataset import body_meshes, choose_bodies

    spec = choose_bodies(library, [r for r, _ in templates], 1, 0)[0]
    meshes = body_meshes(spec)
    by = {}
    for m in meshes:
        by.setdefault(m.name, []).append(m.vertices)
    v = {k: np.concatenate(x) for k, x in by.items()}
    wheelbase = float(library.template_wheelbase_mm[0])
    assert v["headlight"][:, 1].max() < 0 and v["grille"][:, 1].max() < 0        # ahead of the front axle
    assert v["taillight"][:, 1].min() > wheelbase                               # behind the rear axle
    for k in ("headlight", "taillight", "tyre", "rim"):
        assert v[k][:, 0].min() < 0 < v[k][:, 0].max()                           # both sides
    tyre_z = v["tyre"][:, 2]
    assert tyre_z.min() == pytest.approx(-spec.tyre_radius_mm, rel=0.01)
    # the photo-like details: lamps and grille ahead, door mirrors standing out of the body by the
    # side glass; the classic share of a photo-like set gets the classic details back
    from carbody.view.dataset import classic_meshes

    photo = body_meshes(spec, photo_details=True, seed=3)
    pv = {k: np.concatenate([m.vertices for m in photo if m.name == k]) for k in ("headlight", "taillight", "mirror")}
    assert pv["headlight"][:, 1].max() < 0 < wheelbase < pv["taillight"][:, 1].min()
    half_width = spec.control_points_mm[:, 0].max()
    assert pv["mirror"][:, 0].max() > half_width + 100 and pv["mirror"][:, 0].min() < -half_width - 100
    assert 0 < pv["mirror"][:, 1].mean() < wheelbase / 2
    back = classic_meshes(photo)
    assert "mirror" not in {m.name for m in back}
    assert np.allclose(np.concatenate([m.vertices for m in back if m.name == "headlight"]), v["headlight"])


def test_a_body_that_cannot_be_surfaced_is_skipped_and_recorded(tmp_path):
    import json

    from carbody.errors import SurfaceError
    from carbody.view.dataset import read_manifest, render_dataset

    def picky(wireframe):
        if wireframe.name.startswith("toyota"):
            raise SurfaceError("door: outline crosses itself")
        return toy_body(wireframe)

    render_dataset(tmp_path / "s", count=24, seed=0, bodies_per_template=1, surface_body=picky, progress=False,
                   templates=["Volvo V60", "Toyota Camry XV70"])
    rows = read_manifest(tmp_path / "s")
    meta = json.loads((tmp_path / "s" / "dataset.json").read_text())
    assert len(rows) == 24 and {r["template"] for r in rows} == {"Volvo V60"}
    assert meta["skipped_bodies"][0]["body"].startswith("toyota") and "door" in meta["skipped_bodies"][0]["reason"]


@pytest.mark.slow
def test_cli_renders_a_real_dataset_and_trains_on_it(tmp_path):
    """End to end through the commands on real surfaced bodies: render-dataset, train-view, view."""
    pytest.importorskip("carbody.surface")
    run_cli("render-dataset", str(tmp_path / "ds"), "--count", "240", "--bodies-per-template", "1", check=True)
    rows = (tmp_path / "ds" / "manifest.csv").read_text().splitlines()
    assert len(rows) == 241
    out = run_cli("train-view", str(tmp_path / "ds"), "-o", str(tmp_path / "w.pt"), "--epochs", "3", check=True)
    assert "validation accuracy" in out.stdout and (tmp_path / "w.png").exists()
    img = tmp_path / "ds" / rows[1].split(",")[0]
    out = run_cli("view", str(img), "--weights", str(tmp_path / "w.pt"), "--json", check=True)
    assert json.loads(out.stdout)["class_index"] in range(N_CLASSES)
