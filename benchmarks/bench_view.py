"""View classifier: accuracy on cars not in training, confusion matrix, inference time; ablation.

Default run (what ``make bench`` does): render a fresh evaluation set of the validation
templates named in the shipped weights (cars never seen in training; a different seed from the
training set, so every image is new), classify it with the shipped weights, and print top-1
accuracy (24 classes), accuracy within ±15°, the paper's 13-class accuracy (a right-side view
counted by its mirror class), per-elevation accuracy, inference time per image on this CPU and
the training time stored in the weights. Writes ``benchmarks/figures/view_confusion.png``.

    python benchmarks/bench_view.py [--count 480] [--weights W.pt] [--dataset DIR]
    python benchmarks/bench_view.py --ablation [--epochs 25] [--count 1200] [--workdir DIR]

``--ablation`` renders one training set per variation switched off (background, colour,
elevation/camera) plus the full one, at equal size, trains each for the same epochs, and tests
all on the same full-variation renders of the held-out cars.
"""
from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "benchmarks" / "figures"


def evaluation_set(out: Path, count: int, seed: int, templates: list[str]) -> Path:
    from carbody.view.dataset import render_dataset

    render_dataset(out, count=count, seed=seed, bodies_per_template=4, templates=templates, progress=True)
    return out


def classify(dataset: Path, weights: str | None, rows: list[dict]) -> np.ndarray:
    """(N, 24) probabilities of the rows' images."""
    from carbody.view.predict import predict_probabilities

    probs = []
    for i in range(0, len(rows), 64):
        probs.append(predict_probabilities([dataset / r["file"] for r in rows[i:i + 64]], weights))
    return np.concatenate(probs)


def scores(rows: list[dict], probs: np.ndarray) -> dict[str, float]:
    from carbody.view.labels import CLASS_ANGLES_DEG, angular_difference

    y = np.array([r["class_index"] for r in rows])
    pred = probs.argmax(1)
    err = angular_difference(CLASS_ANGLES_DEG[pred], CLASS_ANGLES_DEG[y])
    fold = lambda a: np.where(a > 180, 360 - a, a)   # noqa: E731  the paper's 13 classes
    return {
        "images": len(rows),
        "top1": float((pred == y).mean()),
        "within15": float((err <= 15).mean()),
        "paper13": float((fold(CLASS_ANGLES_DEG[pred]) == fold(CLASS_ANGLES_DEG[y])).mean()),
        "front_rear_confusions": float((err >= 150).mean()),
    }


def confusion_png(rows, probs, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from carbody.view.labels import CLASS_ANGLES_DEG, N_CLASSES

    y = np.array([r["class_index"] for r in rows])
    cm = np.zeros((N_CLASSES, N_CLASSES), dtype=int)
    np.add.at(cm, (y, probs.argmax(1)), 1)
    fig, ax = plt.subplots(figsize=(8, 7))
    norm = cm / np.maximum(cm.sum(1, keepdims=True), 1)
    ax.imshow(norm, cmap="Blues", vmin=0, vmax=1)
    labels = [f"{int(a)}" for a in CLASS_ANGLES_DEG]
    ax.set_xticks(range(N_CLASSES), labels, rotation=90, fontsize=7)
    ax.set_yticks(range(N_CLASSES), labels, fontsize=7)
    for i in range(N_CLASSES):
        for j in range(N_CLASSES):
            if cm[i, j]:
                ax.text(j, i, cm[i, j], ha="center", va="center", fontsize=5,
                        color="white" if norm[i, j] > 0.5 else "black")
    ax.set(xlabel="predicted θ class (°)", ylabel="true θ class (°)", title=title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def inference_ms(image_path: Path, weights: str | None, repeats: int = 200) -> dict[str, float]:
    """Median / 90th-percentile ms per single-image call (decode + resize + network), 1 thread."""
    import torch

    from carbody.view.predict import load_classifier, predict_view

    torch.set_num_threads(1)
    load_classifier(weights)
    out = {}
    for mirror in (False, True):
        for _ in range(10):
            predict_view(image_path, weights, mirror_average=mirror)
        t = []
        for _ in range(repeats):
            s = time.perf_counter()
            predict_view(image_path, weights, mirror_average=mirror)
            t.append((time.perf_counter() - s) * 1000)
        key = "mirror_avg" if mirror else "single"
        out[f"{key}_median_ms"] = statistics.median(t)
        out[f"{key}_p90_ms"] = float(np.percentile(t, 90))
    return out


def main_eval(args) -> None:
    import torch

    from carbody.view.dataset import read_manifest
    from carbody.view.predict import load_classifier

    torch.set_num_threads(1)
    _, meta = load_classifier(args.weights)
    val_templates = meta["dataset"]["validation_templates"]
    if args.dataset:
        dataset = Path(args.dataset)
        rows = [r for r in read_manifest(dataset) if r["split"] == "val"]
        val_templates = sorted({r.get("template", "?") for r in rows})
    else:
        dataset = evaluation_set(Path(tempfile.mkdtemp(prefix="carbody-view-eval-")) / "set", args.count,
                                 args.seed, val_templates)
        rows = read_manifest(dataset)
    t = time.perf_counter()
    probs = classify(dataset, args.weights, rows)
    batch_ms = (time.perf_counter() - t) / len(rows) * 1000
    s = scores(rows, probs)
    confusion = Path(args.confusion) if args.confusion else FIGURES / "view_confusion.png"
    confusion_png(rows, probs, confusion,
                  f"held-out cars ({', '.join(val_templates)}), {len(rows)} renders")
    ms = inference_ms(dataset / rows[0]["file"], args.weights)
    elev = np.array([float(r["elevation_deg"]) for r in rows])
    y = np.array([r["class_index"] for r in rows])
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}, torch {torch.__version__}, 1 thread")
    hist = meta["history"]
    print(f"weights: {len(hist['train_loss'])} epochs, {meta['dataset']['train_images']} training / "
          f"{meta['dataset']['val_images']} validation images, training time {hist['seconds']:.0f} s; "
          f"held-out cars: {', '.join(val_templates)}")
    print(f"evaluation set: {'fresh renders, seed %d' % args.seed if not args.dataset else dataset} "
          f"({len(rows)} images)")
    print("| measure | value |\n|---|---|")
    print(f"| top-1 accuracy, 24 classes (held-out cars) | {s['top1']:.3f} |")
    print(f"| accuracy within ±15° | {s['within15']:.3f} |")
    print(f"| paper's 13 classes (right side folded onto its mirror) | {s['paper13']:.3f} |")
    print(f"| front/rear confusions (error ≥ 150°) | {s['front_rear_confusions']:.3f} |")
    print(f"| final validation accuracy in training (history) | {hist['val_acc'][-1]:.3f} |")
    for lo, hi in ((0, 10), (10, 20), (20, 30.1)):
        m = (elev >= lo) & (elev < hi)
        if m.any():
            print(f"| top-1 at elevation {lo:g}–{min(hi, 30):g}° ({m.sum()} images) | "
                  f"{(probs[m].argmax(1) == y[m]).mean():.3f} |")
    print(f"| inference ms/image, one picture (decode+resize+net), median | {ms['single_median_ms']:.2f} |")
    print(f"| inference ms/image, with mirror averaging (default), median | {ms['mirror_avg_median_ms']:.2f} |")
    print(f"| inference ms/image, with mirror averaging, 90th percentile | {ms['mirror_avg_p90_ms']:.2f} |")
    print(f"| inference ms/image, batches of 64 incl. decode | {batch_ms:.2f} |")
    print(f"| training time (s), from the weights file | {hist['seconds']:.0f} |")
    print(f"confusion matrix: {confusion}")


def main_ablation(args) -> None:
    from carbody.view.dataset import Variation, read_manifest, render_dataset
    from carbody.view.train import TrainConfig, train_view_classifier

    work = Path(args.workdir or tempfile.mkdtemp(prefix="carbody-view-ablation-"))
    variants = {
        "full variation": Variation(),
        "no textured background": Variation(background=False),
        "no colour/light variation": Variation(colour=False),
        "no elevation/camera jitter": Variation(elevation=False),
        "none (plain renders)": Variation(background=False, colour=False, elevation=False),
    }
    # Test set: full variation, the held-out cars, a seed no training set uses.
    test_dir = work / f"test{args.test_count}"
    if not (test_dir / "manifest.csv").exists():
        render_dataset(test_dir, count=args.test_count, seed=args.seed, bodies_per_template=2,
                       progress=True, vary=Variation())
    test_rows = [r for r in read_manifest(test_dir) if r["split"] == "val"]
    results = {}
    only = [x.strip() for x in args.only.split(",")] if args.only else list(variants)
    for name, vary in variants.items():
        if name not in only:
            continue
        d = work / ("v_" + "".join(c for c in name if c.isalnum()))
        if not (d / "manifest.csv").exists():
            render_dataset(d, count=args.count, seed=args.seed, bodies_per_template=2, vary=vary, progress=True)
        w = d / f"weights_e{args.epochs}.pt"
        if not w.exists():
            hist = train_view_classifier(d, w, TrainConfig(epochs=args.epochs, threads=1), progress=True)
            secs = hist.seconds
        else:
            secs = float("nan")
        probs = classify(test_dir, str(w), test_rows)
        results[name] = (scores(test_rows, probs), secs)
        print(name, results[name], flush=True)
    print(f"ablation: {args.count} renders per variant (its training split, about 80 %, used), "
          f"{args.epochs} epochs (cosine lr), tested on {len(test_rows)} full-variation renders of the "
          f"held-out cars ({', '.join(sorted({r['template'] for r in test_rows}))})")
    print("| training renders | top-1 (24) | within ±15° | front/rear confusions |\n|---|---|---|---|")
    for name, (s, _) in results.items():
        print(f"| {name} | {s['top1']:.3f} | {s['within15']:.3f} | {s['front_rear_confusions']:.3f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--weights", default=None, help="weights file (default: shipped)")
    ap.add_argument("--dataset", default=None, help="evaluate the validation split of this data set instead")
    ap.add_argument("--count", type=int, default=480, help="images to render (default 480; ablation 1200)")
    ap.add_argument("--seed", type=int, default=1234)
    ap.add_argument("--confusion", default=None, help="confusion matrix PNG (default benchmarks/figures/)")
    ap.add_argument("--ablation", action="store_true")
    ap.add_argument("--epochs", type=int, default=25, help="ablation: epochs per variant")
    ap.add_argument("--test-count", type=int, default=2400,
                    help="ablation: renders of which the held-out cars' share is the test set")
    ap.add_argument("--workdir", default=None, help="ablation: folder to keep data sets and weights")
    ap.add_argument("--only", default=None, help="ablation: comma-separated variant names to run")
    args = ap.parse_args()
    os.environ.setdefault("CARBODY_CACHE_DIR", tempfile.mkdtemp(prefix="carbody-bench-"))
    if args.ablation:
        if args.count == 480:
            args.count = 1200
        main_ablation(args)
    else:
        main_eval(args)


if __name__ == "__main__":
    sys.exit(main())
