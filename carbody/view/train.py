"""Training of the view classifier (paper III.B): MobileNetV2 from scratch on the rendered set.

Paper settings: 64 × 64 input, learning rate 0.001 (Adam), 50 epochs, batch 64, 8:2 split —
here the split is the data set's own split by car (see :mod:`carbody.view.dataset`), and the
learning rate decays from 0.001 to 0 on a cosine by default (``schedule="constant"`` is the
paper's fixed rate). Training
augments each batch: a left–right flip (its label becomes the mirror class), a shift of up to
4 px (at 64 px), brightness/contrast jitter and occasional grayscale, so photos that differ from
the renders in these ways still classify. A framed photo-like render (its car's box in the
manifest) is cropped afresh each time it is drawn, as a photo of it would be
(:func:`carbody.view.photo.photo_frame_crop`). The final epoch's weights are saved (fp16) with
the training history; validation never selects anything. A checkpoint after every epoch
(``OUTPUT.ckpt``) lets ``resume`` go on after an interruption.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from carbody.errors import ViewError
from carbody.view.ends import END_LOOK_KEY
from carbody.view.labels import CLASS_ANGLES_DEG, MIRROR_PERMUTATION, N_CLASSES

#: Network input side, pixels (paper: 64); a weights file says its own (``input_size``).
INPUT_SIZE = 64

#: Input normalisation: (x / 255 − MEAN) / STD per channel.
MEAN = 0.5
STD = 0.25


@dataclass
class TrainConfig:
    """Hyper-parameters (paper III.B defaults).

    ``schedule`` is ``"cosine"`` (lr decays from ``lr`` to 0 over the epochs, per batch; the
    shipped weights) or ``"constant"`` (the paper's fixed lr; on our data set its last epochs
    swing by ±5 points of validation accuracy, see docs/view_classifier.md).
    """

    epochs: int = 50
    batch_size: int = 64
    lr: float = 0.001
    width_mult: float = 1.0
    seed: int = 0
    threads: int = 1
    augment: bool = True
    schedule: str = "cosine"
    zoom: bool = False
    erase: bool = False
    init: str | None = None
    input_size: int = INPUT_SIZE
    resume: bool = False


@dataclass
class History:
    """Per-epoch curves (the paper's Fig. 5) and timing."""

    train_loss: list[float] = field(default_factory=list)
    train_acc: list[float] = field(default_factory=list)
    val_loss: list[float] = field(default_factory=list)
    val_acc: list[float] = field(default_factory=list)
    seconds: float = 0.0


def to_square_input(image: np.ndarray, size: int = INPUT_SIZE) -> np.ndarray:
    """(size, size, 3) uint8 from an (h, w, 3) uint8 RGB picture: padded to a square by
    repeating its border (keeps the car's aspect ratio), then area-resized."""
    import cv2

    h, w = image.shape[:2]
    if h != w:
        d = abs(h - w)
        a, b = d // 2, d - d // 2
        pad = ((a, b), (0, 0)) if h < w else ((0, 0), (a, b))
        image = cv2.copyMakeBorder(image, *pad[0], *pad[1], cv2.BORDER_REPLICATE)
    interp = cv2.INTER_AREA if image.shape[0] > size else cv2.INTER_LINEAR
    return cv2.resize(image, (size, size), interpolation=interp)


def to_tensor(images: np.ndarray):
    """(B, 3, H, W) float32 torch tensor from (B, H, W, 3) uint8."""
    import torch

    x = torch.from_numpy(np.ascontiguousarray(images)).permute(0, 3, 1, 2).float()
    return (x / 255.0 - MEAN) / STD


def read_rgb(dataset_dir: str | Path, row: dict) -> np.ndarray:
    """(h, w, 3) uint8 RGB of a data set row's image.

    Raises:
        ViewError: not a readable image.
    """
    import cv2

    path = Path(dataset_dir) / row["file"]
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise ViewError(f"{path}: not a readable image")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def network_picture(image: np.ndarray, row: dict, size: int = INPUT_SIZE) -> np.ndarray:
    """(size, size, 3) uint8 input of a data set image as ``carbody view`` would see it: cropped
    to the car's box when the row has one (a framed photo-like render, as ``--box`` crops a
    photo), else the whole picture."""
    from carbody.view.dataset import row_box
    from carbody.view.predict import crop_to_box

    box = row_box(row)
    return to_square_input(image if box is None else crop_to_box(image, box), size)


def load_images(dataset_dir: str | Path, rows: list[dict], progress: bool = True,
                size: int = INPUT_SIZE) -> np.ndarray:
    """(N, size, size, 3) uint8 network inputs of the rows' images (:func:`network_picture`)."""
    from tqdm import tqdm

    from carbody.progress import bar_disabled

    out = np.empty((len(rows), size, size, 3), dtype=np.uint8)
    for i, r in enumerate(tqdm(rows, desc="load", unit="img", disable=bar_disabled(not progress), leave=False)):
        out[i] = network_picture(read_rgb(dataset_dir, r), r, size)
    return out


def augment_batch(x: np.ndarray, y: np.ndarray, rng: np.random.Generator,
                  zoom: bool | np.ndarray = False, erase: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Flip (label mirrored), shift ≤ 1/16 of the side, brightness/contrast jitter, optionally a
    zoom of 0.85–1.2 (60 % of images; ``zoom`` may be a per-image mask), 10 % grayscale, and
    with ``erase`` one random rectangle of noise over half of the images (:func:`erase_patches`)."""
    x = x.copy()
    y = y.copy()
    n, size = len(x), x.shape[1]
    flip = rng.random(n) < 0.5
    x[flip] = x[flip, :, ::-1]
    y[flip] = MIRROR_PERMUTATION[y[flip]]
    m = max(1, size // 16)
    padded = np.pad(x, ((0, 0), (m, m), (m, m), (0, 0)), mode="edge")
    dx, dy = rng.integers(0, 2 * m + 1, n), rng.integers(0, 2 * m + 1, n)
    for i in range(n):
        x[i] = padded[i, dy[i]:dy[i] + size, dx[i]:dx[i] + size]
    xf = x.astype(np.float32)
    contrast = rng.uniform(0.75, 1.25, (n, 1, 1, 1))
    bright = rng.uniform(-25, 25, (n, 1, 1, 1))
    mean = xf.mean(axis=(1, 2, 3), keepdims=True)
    xf = (xf - mean) * contrast + mean + bright
    zoom_mask = np.broadcast_to(np.asarray(zoom, dtype=bool), (n,))
    if zoom_mask.any():          # the car's box is never exact: zoom 0.85-1.2 about a jittered centre
        import cv2

        for i in np.flatnonzero((rng.random(n) < 0.6) & zoom_mask):
            s = rng.uniform(0.85, 1.2)
            c = size / 2 + rng.uniform(-3, 3, 2) * size / 64
            a = np.array([[s, 0, (1 - s) * c[0]], [0, s, (1 - s) * c[1]]])
            xf[i] = cv2.warpAffine(xf[i], a, (size, size), borderMode=cv2.BORDER_REPLICATE)
    grey = rng.random(n) < 0.1
    xf[grey] = xf[grey].mean(axis=3, keepdims=True)
    if erase:
        erase_patches(xf, rng)
    return np.clip(xf, 0, 255).astype(np.uint8), y


def erase_patches(x: np.ndarray, rng: np.random.Generator, share: float = 0.5,
                  area: tuple[float, float] = (0.02, 0.2)) -> None:
    """Random erasing, in place on (n, s, s, 3) float images: on ``share`` of them one rectangle of
    ``area`` of the picture (aspect 0.3–3.3) is filled with uniform noise. A car hidden in part
    must be told by what else shows: its ends' lamps, grille and glass, not only its side's
    layout."""
    n, size = len(x), x.shape[1]
    for i in np.flatnonzero(rng.random(n) < share):
        a = rng.uniform(*area) * size * size
        r = np.exp(rng.uniform(np.log(0.3), np.log(3.3)))
        h, w = (min(size, max(1, int(round(np.sqrt(a * r))))), min(size, max(1, int(round(np.sqrt(a / r))))))
        top, left = rng.integers(0, size - h + 1), rng.integers(0, size - w + 1)
        x[i, top:top + h, left:left + w] = rng.uniform(0, 255, (h, w, 3))


def evaluate(model, x: np.ndarray, y: np.ndarray, batch_size: int = 256) -> tuple[float, float, np.ndarray]:
    """(mean cross-entropy, top-1 accuracy, (N, 24) probabilities) of a model on inputs."""
    import torch

    model.eval()
    probs, losses = [], []
    with torch.no_grad():
        for i in range(0, len(x), batch_size):
            logits = model(to_tensor(x[i:i + batch_size]))
            losses.append(torch.nn.functional.cross_entropy(
                logits, torch.from_numpy(y[i:i + batch_size]).long(), reduction="sum").item())
            probs.append(torch.softmax(logits, 1).numpy())
    p = np.concatenate(probs) if probs else np.zeros((0, N_CLASSES))
    return float(sum(losses) / max(1, len(x))), float((p.argmax(1) == y).mean()) if len(y) else 0.0, p


def train_view_classifier(dataset_dir, output: str | Path, config: TrainConfig = TrainConfig(),
                          plot: str | Path | None = None, progress: bool = True) -> History:
    """Train MobileNetV2 on a rendered data set and save the weights (fp16) and a Fig. 5 plot.

    Args:
        dataset_dir: a folder written by :func:`carbody.view.dataset.render_dataset` (or class
            folders of images named by angle), or a list of such folders trained on together
            (split alike: :func:`carbody.view.dataset.read_datasets`).
        output: the weights file (``.pt``) to write.
        plot: loss/accuracy curves PNG (default: ``output`` with ``.png``).

    Returns:
        The :class:`History`.

    Raises:
        ViewError: unreadable data set, no training or validation images, bad settings.
    """
    import torch
    from tqdm import tqdm

    from carbody.progress import bar_disabled
    from carbody.view.dataset import dataset_folders, read_datasets
    from carbody.view.network import build_mobilenet_v2

    if config.epochs < 1 or config.batch_size < 1 or not (config.lr > 0):
        raise ViewError("epochs, batch size and learning rate must be positive")
    if config.schedule not in ("constant", "cosine"):
        raise ViewError(f"unknown learning-rate schedule {config.schedule!r} (constant or cosine)")
    output = Path(output)
    if output.suffix != ".pt":
        raise ViewError(f"{output}: the weights file must end in .pt")
    rows = read_datasets(dataset_dir)
    folders = dataset_folders(dataset_dir)
    dataset_dir = folders[0]  # (rows of several folders name their images by absolute path)
    train_rows = [r for r in rows if r["split"] == "train"]
    val_rows = [r for r in rows if r["split"] == "val"]
    if not train_rows or not val_rows:
        raise ViewError(f"{dataset_dir}: needs both training and validation images "
                        f"({len(train_rows)} and {len(val_rows)})")
    size = int(config.input_size)
    if not 32 <= size <= 256:
        raise ViewError(f"input size must be 32..256 px, got {size}")
    torch.set_num_threads(max(1, int(config.threads)))
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    from carbody.view.dataset import row_box

    x_train = load_images(dataset_dir, train_rows, progress, size)
    y_train = np.array([r["class_index"] for r in train_rows], dtype=np.int64)
    x_val = load_images(dataset_dir, val_rows, progress, size)
    y_val = np.array([r["class_index"] for r in val_rows], dtype=np.int64)
    # framed renders are cropped afresh at every draw, from the stored picture
    framed = np.array([row_box(r) is not None for r in train_rows], dtype=bool)
    pictures = {i: read_rgb(dataset_dir, train_rows[i]) for i in np.flatnonzero(framed)} if config.augment else {}
    boxes = {i: row_box(train_rows[i]) for i in pictures}

    model = build_mobilenet_v2(N_CLASSES, width_mult=config.width_mult)
    if config.init:         # go on from earlier weights (a longer schedule in two runs)
        payload = torch.load(config.init, map_location="cpu", weights_only=True)
        model.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in payload["state_dict"].items()})
    opt = torch.optim.Adam(model.parameters(), lr=config.lr)
    steps = config.epochs * -(-len(x_train) // config.batch_size)
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, (lambda i: 0.5 * (1 + np.cos(np.pi * min(i, steps) / steps))) if config.schedule == "cosine"
        else (lambda i: 1.0))
    hist = History()
    checkpoint = output.with_suffix(".ckpt")
    first_epoch = 0
    if config.resume and checkpoint.exists():
        state = torch.load(checkpoint, map_location="cpu", weights_only=False)
        model.load_state_dict(state["model"])
        opt.load_state_dict(state["optimizer"])
        sched.load_state_dict(state["scheduler"])
        rng.bit_generator.state = state["rng"]
        torch.set_rng_state(state["torch_rng"])
        hist = History(**state["history"])
        first_epoch = len(hist.train_loss)
    from carbody.view.photo import photo_frame_crop

    t0 = time.perf_counter() - hist.seconds
    bar = tqdm(range(first_epoch, config.epochs), desc="train-view", unit="epoch", disable=bar_disabled(not progress))
    for _ in bar:
        model.train()
        order = rng.permutation(len(x_train))
        loss_sum, correct = 0.0, 0
        for i in range(0, len(order), config.batch_size):
            idx = order[i:i + config.batch_size]
            if len(idx) < 2:          # BatchNorm needs two samples
                continue
            xb, yb = x_train[idx], y_train[idx]
            if config.augment:
                xb = xb.copy()
                for j, k in enumerate(idx):
                    if k in pictures:
                        xb[j] = photo_frame_crop(pictures[k], boxes[k], rng, size)
                xb, yb = augment_batch(xb, yb, rng, zoom=config.zoom & ~framed[idx], erase=config.erase)
            logits = model(to_tensor(xb))
            target = torch.from_numpy(yb)
            loss = torch.nn.functional.cross_entropy(logits, target)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            loss_sum += loss.item() * len(idx)
            correct += int((logits.argmax(1) == target).sum())
        hist.train_loss.append(loss_sum / len(order))
        hist.train_acc.append(correct / len(order))
        vl, va, _ = evaluate(model, x_val, y_val)
        hist.val_loss.append(vl)
        hist.val_acc.append(va)
        bar.set_postfix(loss=f"{hist.train_loss[-1]:.3f}", acc=f"{hist.train_acc[-1]:.3f}",
                        val_loss=f"{vl:.3f}", val_acc=f"{va:.3f}")
        hist.seconds = time.perf_counter() - t0
        _save_checkpoint(checkpoint, model, opt, sched, rng, hist)
    hist.seconds = time.perf_counter() - t0
    save_weights(model, output, config, hist, folders, rows)
    checkpoint.unlink(missing_ok=True)
    plot_history(hist, plot or output.with_suffix(".png"))
    return hist


def _save_checkpoint(path: Path, model, opt, sched, rng: np.random.Generator, hist: History) -> None:
    """Everything a resumed run needs after an epoch (written atomically)."""
    import os

    import torch

    state = {"model": model.state_dict(), "optimizer": opt.state_dict(), "scheduler": sched.state_dict(),
             "rng": rng.bit_generator.state, "torch_rng": torch.get_rng_state(),
             "history": {k: getattr(hist, k) for k in hist.__dataclass_fields__}}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    torch.save(state, tmp)
    os.replace(tmp, path)


def save_weights(model, output: Path, config: TrainConfig, hist: History, dataset_dir, rows) -> Path:
    """fp16 state dict plus what a reader needs (classes, input, normalisation, history), atomically.
    ``dataset_dir``: the data set's folder, or the list of folders trained on together."""
    import json
    import os

    import torch

    from carbody.view.dataset import dataset_folders

    folders = dataset_folders(dataset_dir)
    meta_path = folders[0] / "dataset.json"
    dataset_meta = json.loads(meta_path.read_text()) if meta_path.exists() else {}
    end_looks = [d.name for d in folders if (d / "dataset.json").exists()
                 and END_LOOK_KEY in json.loads((d / "dataset.json").read_text())]
    payload = {
        "format": "carbody-view-mobilenetv2/1",
        "state_dict": {k: (v.half() if v.is_floating_point() else v) for k, v in model.state_dict().items()},
        "num_classes": N_CLASSES,
        "classes_deg": CLASS_ANGLES_DEG.tolist(),
        "width_mult": config.width_mult,
        "input_size": int(config.input_size),
        "mean": MEAN,
        "std": STD,
        "config": vars(config) if not hasattr(config, "__dataclass_fields__") else
        {k: getattr(config, k) for k in config.__dataclass_fields__},
        "history": {"train_loss": hist.train_loss, "train_acc": hist.train_acc,
                    "val_loss": hist.val_loss, "val_acc": hist.val_acc, "seconds": hist.seconds},
        "dataset": {"images": len(rows), "train_images": sum(r["split"] == "train" for r in rows),
                    "val_images": sum(r["split"] == "val" for r in rows),
                    "validation_templates": dataset_meta.get("validation_templates", []),
                    "seed": dataset_meta.get("seed"), "variation": dataset_meta.get("variation"),
                    "folders": [d.name for d in folders]},
    }
    if end_looks:    # the near end's looks too: predict_probabilities takes its second look
        payload[END_LOOK_KEY] = {"folders": end_looks}
    output.parent.mkdir(parents=True, exist_ok=True)
    tmp = output.with_name(f".{output.name}.{os.getpid()}.tmp")
    torch.save(payload, tmp)
    os.replace(tmp, output)
    return output


def plot_history(hist: History, path: str | Path) -> Path:
    """The paper's Fig. 5: (a) training/validation accuracy, (b) training/validation loss, per epoch."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    epochs = np.arange(1, len(hist.train_loss) + 1)
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    a.plot(epochs, hist.train_acc, label="training")
    a.plot(epochs, hist.val_acc, label="validation (held-out cars)")
    a.set(xlabel="epoch", ylabel="accuracy", title="(a) accuracy", ylim=(0, 1.02))
    b.plot(epochs, hist.train_loss, label="training")
    b.plot(epochs, hist.val_loss, label="validation (held-out cars)")
    b.set(xlabel="epoch", ylabel="cross-entropy loss", title="(b) loss")
    for ax in (a, b):
        ax.grid(alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


#: What every ingredient of a soup must share with the first (they are one network).
SOUP_SAME = ("format", "num_classes", "classes_deg", "width_mult", "input_size", "mean", "std")


def check_soup_output(weights: list[str | Path], output: str | Path) -> None:
    """Refuse a soup written over one of its own ingredients.

    Raises:
        ViewError: ``output`` is one of ``weights``.
    """
    if Path(output).resolve() in {Path(w).resolve() for w in weights}:
        raise ViewError(f"{output}: is one of the weights averaged; write the soup to another file")


def average_weights(weights: list[str | Path], output: str | Path) -> dict:
    """A uniform model soup (Wortsman et al., ICML 2022): the mean of the weights of networks
    fine-tuned from the same start, written as one weights file of the same size.

    Networks fine-tuned from one start stay in one basin of the loss, so their mean is a network
    too, and a better one than the typical ingredient: the seeds' spread averages out. The
    BatchNorm statistics are averaged as well. The soup keeps no temperature (1): calibrate it
    (:func:`carbody.view.calibrate.calibrate_weights`) before use.

    Returns:
        The payload written (``soup``: each ingredient's file, start, seed, epochs and last
        validation accuracy).

    Raises:
        ViewError: fewer than two files, the output one of them, a file that is not view weights,
            or ingredients that differ in network, input, held-out cars or start (or were trained
            from scratch).
    """
    import torch

    paths = [Path(w) for w in weights]
    if len(paths) < 2:
        raise ViewError(f"a soup needs at least two weights files, got {len(paths)}")
    check_soup_output(paths, output)
    payloads = []
    for p in paths:
        try:
            payloads.append(torch.load(p, map_location="cpu", weights_only=True))
        except Exception as e:  # noqa: BLE001 - any unreadable file is the same one-line refusal
            raise ViewError(f"{p}: not a view classifier's weights ({type(e).__name__})") from None
        if not isinstance(payloads[-1], dict) or "state_dict" not in payloads[-1]:
            raise ViewError(f"{p}: not a view classifier's weights (no state_dict)")
    first = payloads[0]
    held_out = lambda q: sorted((q.get("dataset") or {}).get("validation_templates") or [])  # noqa: E731
    start = lambda q: (q.get("config") or {}).get("init")  # noqa: E731
    for p, q in zip(paths, payloads):
        if start(q) is None:
            raise ViewError(f"{p}: trained from scratch; a soup averages networks fine-tuned from the same "
                            f"weights (train-view --init)")
        for key in SOUP_SAME:
            if q.get(key) != first.get(key):
                raise ViewError(f"{p}: {key} {q.get(key)!r} differs from {paths[0].name}'s {first.get(key)!r}")
        if held_out(q) != held_out(first):
            raise ViewError(f"{p}: holds out other cars than {paths[0].name}; their renders would not be "
                            f"held out from the soup")
        if start(q) != start(first):
            raise ViewError(f"{p}: fine-tuned from {start(q)}, {paths[0].name} from {start(first)}; "
                            f"a soup needs one start")
        if bool(q.get(END_LOOK_KEY)) != bool(first.get(END_LOOK_KEY)):
            raise ViewError(f"{p}: {'learnt' if q.get(END_LOOK_KEY) else 'did not learn'} the near end's looks, "
                            f"{paths[0].name} {'did' if first.get(END_LOOK_KEY) else 'did not'}; a soup needs one kind")
        shapes = {k: tuple(v.shape) for k, v in q["state_dict"].items()}
        if shapes != {k: tuple(v.shape) for k, v in first["state_dict"].items()}:
            raise ViewError(f"{p}: its layers differ from {paths[0].name}'s")
    state = {}
    for k, v in first["state_dict"].items():
        if v.is_floating_point():
            mean = sum(q["state_dict"][k].double() for q in payloads) / len(payloads)
            state[k] = mean.to(v.dtype)
        else:          # BatchNorm's batch counters
            state[k] = max((q["state_dict"][k] for q in payloads), key=int)
    payload = {k: first[k] for k in SOUP_SAME} | {k: first[k] for k in (END_LOOK_KEY,) if k in first} | {
        "state_dict": state,
        "config": {"soup": len(payloads), "init": start(first)},
        "history": {"train_loss": [], "train_acc": [], "val_loss": [], "val_acc": [],   # trained by none
                    "seconds": float(sum(q["history"].get("seconds", 0.0) for q in payloads))},
        "dataset": first["dataset"] | {"folders": sorted({f for q in payloads for f in q["dataset"].get("folders", [])})},
        "soup": [{"file": p.name, "init": start(q), "seed": q["config"].get("seed"),
                  "epochs": q["config"].get("epochs"), "erase": q["config"].get("erase", False),
                  "folders": q["dataset"].get("folders", []), "val_acc": q["history"]["val_acc"][-1]}
                 for p, q in zip(paths, payloads)],
    }
    from carbody.occ.step_curves import atomic_write

    atomic_write(output, lambda tmp: torch.save(payload, tmp))
    return payload
