"""View classifier: accuracy on cars not in training, confusion matrix, inference time; ablation.

Default run (what ``make bench`` does): render a fresh evaluation set of the validation
templates named in the shipped weights (cars never seen in training; a different seed from the
training set, so every image is new), classify it with the shipped weights, and print top-1
accuracy (24 classes), accuracy within ±15°, the paper's 13-class accuracy (a right-side view
counted by its mirror class), per-elevation accuracy, inference time per image on this CPU and
the training time stored in the weights. Writes ``benchmarks/figures/view_confusion.png``.

    python benchmarks/bench_view.py [--count 480] [--weights W.pt] [--dataset DIR]
    python benchmarks/bench_view.py --ablation [--epochs 25] [--count 1200] [--workdir DIR]
    python benchmarks/bench_view.py --real [--weights W.pt] [--photos ../shared/realphotos]
    python benchmarks/bench_view.py --looks [--weights W.pt] [--workdir DIR]
    python benchmarks/bench_view.py --speed [--weights W.pt|W.onnx] [--repeats 200] [--threads 1]
    python benchmarks/bench_view.py --photo-ablation [--epochs 40] [--count 4800] [--workdir DIR] [--only "B;C"]
                                    [--width 0.5] [--train-seed 1] [--measure LABEL=W.pt] [--table]

``--real`` classifies the 27 real photos of ``../shared/realphotos`` (measurement only: nothing
is copied or trained on them) against the views estimated by eye in their keypoint files (±10°):
the whole photo, the car's box (the union of the data set's part polygons) and the box of the
hand-clicked marks (grown as ``carbody view -k`` grows it), each with within ±15° / ±30°,
front/rear and left/right confusions, and a reliability table of the probabilities. It skips
with a message when the folder is absent.

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


def _eval_photo_look():
    from carbody.view.photo import PhotoLook

    return PhotoLook(tone=False, plate_colours=False)


def evaluation_set(out: Path, count: int, seed: int, templates: list[str], photo_like: bool = False) -> Path:
    from carbody.view.dataset import Variation, render_dataset
    from carbody.view.photo import PhotoLook

    # the photo-like test renders: every change of the ablation's row D (fixed, so every row and the
    # final weights are measured on the same pictures)
    vary = Variation(photo=_eval_photo_look()) if photo_like else Variation()
    render_dataset(out, count=count, seed=seed, bodies_per_template=4, templates=templates, progress=True, vary=vary)
    return out


def classify(dataset: Path, weights: str | None, rows: list[dict]) -> np.ndarray:
    """(N, 24) probabilities of the rows' images; a framed photo-like render is cropped to its
    car's box, as ``carbody view --box`` crops a photo."""
    from carbody.view.dataset import row_box
    from carbody.view.predict import predict_probabilities

    probs = []
    for i in range(0, len(rows), 64):
        chunk = rows[i:i + 64]
        probs.append(predict_probabilities([dataset / r["file"] for r in chunk], weights,
                                           boxes=[row_box(r) for r in chunk]))
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


def timed_ms(call, repeats: int, warm_up: int = 10) -> tuple[list[float], list[float]]:
    """([wall ms], [CPU ms]) of ``repeats`` calls of ``call()``, after ``warm_up`` untimed ones."""
    for _ in range(warm_up):
        call()
    wall, cpu = [], []
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        call()
        wall.append((time.perf_counter() - w0) * 1000)
        cpu.append((time.process_time() - c0) * 1000)
    return wall, cpu


def inference_ms(image_path: Path, weights: str | None, repeats: int = 200) -> dict[str, float]:
    """Median / 90th-percentile ms per single-image call (decode + resize + network), 1 thread."""
    import torch
    from threadpoolctl import threadpool_limits

    from carbody.view.predict import load_classifier, predict_view

    torch.set_num_threads(1)
    load_classifier(weights)
    out = {}
    with threadpool_limits(1):
        for mirror in (False, True):
            t, _ = timed_ms(lambda: predict_view(image_path, weights, mirror_average=mirror), repeats)
            key = "mirror_avg" if mirror else "single"
            out[f"{key}_median_ms"] = statistics.median(t)
            out[f"{key}_p90_ms"] = float(np.percentile(t, 90))
    return out


def runtime_version() -> str:
    """The network's runtime and its version, for the speed table's heading."""
    from carbody.view.onnx_net import onnxruntime_module

    return f"ONNX Runtime {onnxruntime_module().__version__}"


def main_speed(args) -> int:
    """Per-picture inference as ``carbody view --box`` runs it (decode + crop + resize + the
    exported network in ONNX Runtime with mirror averaging, no torch; a second look at the near
    end of a three-quarter view, :mod:`carbody.view.ends`), wall and CPU time,
    one BLAS thread and ``--threads`` threads for OpenCV and the network (1: as a batch worker
    runs it; the cores: as ``carbody view`` runs it, OpenCV's default); a ``.pt`` is exported to a temporary ``.onnx``
    first. The load average is printed: on the shared machine the wall time grows with it, the
    CPU time much less."""
    import cv2
    from threadpoolctl import threadpool_limits

    from carbody.view.ends import END_LOOK_KEY, end_look, is_three_quarter
    from carbody.view.onnx_net import load_onnx_classifier, onnx_weights_for, probabilities
    from carbody.view.predict import crop_to_box, predict_view, read_image
    from carbody.view.train import to_square_input

    if args.threads < 1:
        print(f"bench_view: --threads must be at least 1, not {args.threads}", file=sys.stderr)
        return 2
    weights = args.weights
    if weights and Path(weights).suffix == ".pt":
        from carbody.view.onnx_net import export_weights

        exported = Path(tempfile.mkdtemp(prefix="carbody-view-speed-")) / "w.onnx"
        export_weights(weights, exported)
        weights = str(exported)
    root = Path(args.photos) if args.photos else REAL_PHOTOS
    photos = real_photo_set(root) if (root / "keypoints").is_dir() else []
    if photos:
        image, box = photos[0]["image"], photos[0]["parts_box"]
    else:                        # no shared photos: a synthetic 800 x 600 picture
        image, box = np.random.default_rng(0).integers(0, 255, (600, 800, 3), dtype=np.uint8), (100, 150, 700, 450)
    cv2.setNumThreads(args.threads)  # OpenCV's pool, and the network's (carbody.view.onnx_net)
    size = load_onnx_classifier(onnx_weights_for(weights)).meta["input_size"]
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, load average "
          f"{' / '.join(f'{x:.1f}' for x in os.getloadavg())} (1/5/15 min); {runtime_version()}, {size} px input, "
          f"{args.threads} thread(s); picture {Path(image).name if photos else 'synthetic'} with its box")
    print("| call | wall ms median | wall ms 90th pct | CPU ms median |\n|---|---|---|---|")
    picture = read_image(image)
    x = to_square_input(crop_to_box(picture, box), size)[None]
    view = predict_view(picture, weights, box=box, end_looks=False).theta_deg
    second = is_three_quarter(view) and bool(load_onnx_classifier(onnx_weights_for(weights)).meta.get(END_LOOK_KEY))
    x_end = to_square_input(crop_to_box(end_look(picture, box, view), box), size)[None]
    net = lambda: probabilities(x, onnx_weights_for(weights), True)  # noqa: E731
    calls = [("whole call (decode + crop + network), mirror averaged, the default"
              + (": two looks" if second else ": one look"), lambda: predict_view(image, weights, box=box)),
             ("whole call, mirror averaged, one look", lambda: predict_view(image, weights, box=box, end_looks=False)),
             ("network alone, mirror averaged, one look", net)]
    if second:      # the picture and the weights take a second look: what it costs the network
        calls.append(("network alone, mirror averaged, two looks",
                      lambda: (net(), probabilities(x_end, onnx_weights_for(weights), True))))
    with threadpool_limits(1):
        for label, call in calls:
            wall, cpu = timed_ms(call, args.repeats)
            print(f"| {label} | {statistics.median(wall):.2f} | {np.percentile(wall, 90):.2f} | "
                  f"{statistics.median(cpu):.2f} |")
    print(f"load average after: {' / '.join(f'{x:.1f}' for x in os.getloadavg())}")
    return 0


def main_eval(args) -> None:
    import torch

    from carbody.view.dataset import read_manifest
    from carbody.view.predict import load_classifier

    torch.set_num_threads(1)
    _, meta = load_classifier(args.weights)
    val_templates = meta["dataset"]["validation_templates"]
    if args.templates:      # e.g. another model's held-out cars, to compare two weights on one set
        val_templates = [t.strip() for t in args.templates.split(",")]
    if args.dataset:
        dataset = Path(args.dataset)
        rows = [r for r in read_manifest(dataset) if r["split"] == "val"]
        val_templates = sorted({r.get("template", "?") for r in rows})
    else:
        dataset = evaluation_set(Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="carbody-view-eval-")) / "set", args.count,
                                 args.seed, val_templates, args.photo_like)
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
    soup = meta.get("soup") or []
    trained = (f"a soup of {len(soup)} fine-tunes ({', '.join(str(i['epochs']) for i in soup)} epochs)" if soup
               else f"{len(hist['train_loss'])} epochs")
    print(f"weights: {trained}, {meta['dataset']['train_images']} training / "
          f"{meta['dataset']['val_images']} validation images, training time {hist['seconds']:.0f} s; "
          f"held-out cars: {', '.join(val_templates)}")
    print(f"evaluation set: {'fresh %s renders, seed %d' % ('photo-like' if args.photo_like else 'classic', args.seed) if not args.dataset else dataset} "
          f"({len(rows)} images)")
    print("| measure | value |\n|---|---|")
    print(f"| top-1 accuracy, 24 classes (held-out cars) | {s['top1']:.3f} |")
    print(f"| accuracy within ±15° | {s['within15']:.3f} |")
    print(f"| paper's 13 classes (right side folded onto its mirror) | {s['paper13']:.3f} |")
    print(f"| front/rear confusions (error ≥ 150°) | {s['front_rear_confusions']:.3f} |")
    if soup:
        accs = " / ".join(f"{i['val_acc']:.3f}" for i in soup)
        print(f"| its fine-tunes' last validation accuracy in training | {accs} |")
    else:
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
        w = d / f"weights_e{args.epochs}{'' if zoom else '_nozoom'}.pt"
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


# ----------------------------------------------------------------------------------- real photos

REAL_PHOTOS = ROOT.parent / "shared" / "realphotos"


def real_photo_set(root: Path) -> list[dict]:
    """One dict per photo: image path, view estimate (deg), marks {name: (u, v)}, parts box."""
    import json

    parts = json.loads((root / "parts.json").read_text())
    ids = {im["file_name"]: im["id"] for im in parts["images"]}
    boxes: dict[int, list] = {}
    for a in parts["annotations"]:
        x, y, w, h = a["bbox"]
        boxes.setdefault(a["image_id"], []).append((x, y, x + w, y + h))
    out = []
    for f in sorted((root / "keypoints").glob("*.json")):
        d = json.loads(f.read_text())
        b = np.array(boxes.get(ids.get(d["image"]), []), dtype=float)
        out.append({"name": f.stem, "image": root / "images" / d["image"],
                    "estimate_deg": float(d["view_estimate_deg"]) % 360.0,
                    "marks": {k: tuple(v) for k, v in d["keypoints"].items()},
                    "parts_box": (b[:, 0].min(), b[:, 1].min(), b[:, 2].max(), b[:, 3].max()) if len(b) else None})
    return out


def confusion_kind(pred_deg: float, true_deg: float) -> str:
    """``ok`` (within 30°), else which mistake the prediction is nearest to: ``front/rear``
    (θ ↔ 180° − θ, same side, ends swapped), ``left/right`` (θ ↔ 360° − θ, the mirror image),
    ``both`` (θ ↔ θ + 180°) or ``other``."""
    from carbody.view.labels import angular_difference

    if angular_difference(pred_deg, true_deg) <= 30:
        return "ok"
    cands = {"front/rear": 180.0 - true_deg, "left/right": 360.0 - true_deg, "both": true_deg + 180.0}
    kind, d = min(((k, float(angular_difference(pred_deg, a))) for k, a in cands.items()), key=lambda kv: kv[1])
    return kind if d <= 30 else "other"


def real_scores(pred_deg: np.ndarray, true_deg: np.ndarray) -> dict[str, float]:
    from carbody.view.labels import angular_difference

    from bench_real_photos import view_lean_deg

    err = angular_difference(pred_deg, true_deg)
    kinds = [confusion_kind(p, t) for p, t in zip(pred_deg, true_deg)]
    n = max(1, len(kinds))
    # the lean (bench_real_photos): on three-quarter views read in the estimate's quarter, how
    # much nearer the car's end (−) or side (+) the prediction is than the estimate
    leans = [view_lean_deg(p, t) for p, t, e in zip(pred_deg, true_deg, err) if e <= LEAN_WITHIN_DEG]
    leans = [v for v in leans if v is not None]
    return {"n": len(kinds), "within15": float((err <= 15).mean()), "within30": float((err <= 30).mean()),
            "front_rear": sum(k in ("front/rear", "both") for k in kinds) / n,
            "left_right": sum(k in ("left/right", "both") for k in kinds) / n,
            "median_err": float(np.median(err)), "kinds": kinds, "err": err,
            "lean": float(np.median(leans)) if leans else float("nan"), "lean_n": len(leans)}


#: The lean is read on predictions within this of the estimate (the estimate's quarter).
LEAN_WITHIN_DEG = 45.0


def neighbour_mass(probs: np.ndarray) -> np.ndarray:
    """(B,) probability that the view's class is the top class or one of its two neighbours."""
    k = probs.argmax(1)
    n = probs.shape[1]
    idx = np.stack([(k - 1) % n, k, (k + 1) % n], 1)
    return np.take_along_axis(probs, idx, 1).sum(1)


def reliability_rows(conf: np.ndarray, hit: np.ndarray, edges=(0.0, 0.5, 0.7, 0.85, 0.95, 1.0001)) -> list:
    """[(bin label, count, mean confidence, hit rate)] and the expected calibration error."""
    rows, ece = [], 0.0
    for lo, hi in zip(edges[:-1], edges[1:]):
        m = (conf >= lo) & (conf < hi)
        if m.any():
            rows.append((f"{lo:.2f}–{min(hi, 1):.2f}", int(m.sum()), float(conf[m].mean()), float(hit[m].mean())))
            ece += m.mean() * abs(conf[m].mean() - hit[m].mean())
    return rows, float(ece)


def main_real(args) -> int:
    import torch

    from carbody.view.labels import CLASS_ANGLES_DEG, angular_difference
    from carbody.view.predict import load_classifier, keypoint_box, predict_probabilities

    root = Path(args.photos) if args.photos else REAL_PHOTOS
    if not (root / "keypoints").is_dir():
        print(f"skipped: no real photos at {root} (the shared folder is not here)")
        return 0
    torch.set_num_threads(1)
    photos = real_photo_set(root)
    _, meta = load_classifier(args.weights)
    truth = np.array([p["estimate_deg"] for p in photos])
    settings = {
        "full photo": [None] * len(photos),
        "car's box (part polygons)": [p["parts_box"] for p in photos],
        "box of the marks (carbody view -k)": [keypoint_box(p["marks"]) for p in photos],
    }
    print(f"real photos: {len(photos)} from {root} (views estimated by eye, ±10°); weights "
          f"{args.weights or 'shipped'}, temperature {float(meta.get('temperature', 1.0)):.2f}")
    print("| input | within ±15° | within ±30° | front/rear confusions | left/right confusions | median error (°) "
          "| three-quarter views: median lean ° (n) |")
    print("|---|---|---|---|---|---|---|")
    from carbody.view.ends import END_LOOK_KEY

    looks = [("", True)] + ([(" (one look: the whole car's alone)", False)] if meta.get(END_LOOK_KEY) else [])
    results = {}
    for (label, boxes), (tag, end_looks) in ((kv, lk) for kv in list(settings.items()) for lk in looks):
        if boxes[0] is None and not end_looks:
            continue                                     # no box, no second look
        label = label + tag
        probs = predict_probabilities([p["image"] for p in photos], args.weights, boxes=boxes,
                                      end_looks=end_looks)
        from carbody.view.labels import continuous_estimate

        pred = np.array([continuous_estimate(q) for q in probs])
        s = real_scores(pred, truth)
        results[label] = (s, probs, pred)
        if label == "box of the marks (carbody view -k)":     # and what the marks' names say of the view
            from carbody.view.marks import combine_with_marks

            probs_m = np.array([combine_with_marks(q, p["marks"]) for q, p in zip(probs, photos)])
            pred_m = np.array([continuous_estimate(q) for q in probs_m])
            sm = real_scores(pred_m, truth)
            results["marks' box and names"] = (sm, probs_m, pred_m)
        print(f"| {label} | {s['within15']:.2f} | {s['within30']:.2f} | {s['front_rear']:.2f} | "
              f"{s['left_right']:.2f} | {s['median_err']:.0f} | {s['lean']:+.1f} ({s['lean_n']}) |")
    if "marks' box and names" in results:
        sm = results["marks' box and names"][0]
        print(f"| box of the marks × their names' view likelihood (carbody view -k) | {sm['within15']:.2f} | "
              f"{sm['within30']:.2f} | {sm['front_rear']:.2f} | {sm['left_right']:.2f} | {sm['median_err']:.0f} | "
              f"{sm['lean']:+.1f} ({sm['lean_n']}) |")
        settings = {**settings, "marks' box and names": None}
    if args.verbose:
        print("| photo | estimate | " + " | ".join(settings) + " |\n|---|---|" + "---|" * len(settings))
        for i, p in enumerate(photos):
            cells = [f"{results[k][2][i]:.0f} ({results[k][0]['kinds'][i]})" for k in settings]
            print(f"| {p['name']} | {truth[i]:.0f} | " + " | ".join(cells) + " |")
    if args.recolour:
        recolour_table(photos, truth, args.weights)
    # Reliability on the car's box: P(top class or a neighbour) against |top class − estimate| ≤ 22.5°.
    s, probs, _ = results["car's box (part polygons)"]
    conf = neighbour_mass(probs)
    hit = angular_difference(CLASS_ANGLES_DEG[probs.argmax(1)], truth) <= 22.5
    rows, ece = reliability_rows(conf, hit)
    print("reliability, car's box: P(the view's class is the top class or a neighbour) against "
          "the top class lying within 22.5° of the estimate")
    print("| P bin | photos | mean P | observed rate |\n|---|---|---|---|")
    for label, n, c, h in rows:
        print(f"| {label} | {n} | {c:.2f} | {h:.2f} |")
    print(f"expected calibration error {ece:.3f}, mean P {conf.mean():.2f}, observed {hit.mean():.2f}")
    return 0


#: The shipped rule's name among :func:`_look_rules`.
SHIPPED_RULE = "the whole car × the near end's facing (shipped)"


def _look_rules() -> dict:
    """The ways the two looks may vote (``--looks``): each maps the whole car's class
    probabilities p and the near end's q to the call. The shipped rule is
    :func:`carbody.view.ends.combine_looks`."""
    from carbody.view.ends import combine_looks

    return {
        "one look: the whole car alone": lambda p, q: p,
        SHIPPED_RULE: combine_looks,
        "the whole car's axis × the near end's facing": lambda p, q: combine_looks(p + np.roll(p, len(p) // 2), q),
    }


def look_cases(ends: dict, plain: dict) -> list[tuple[str, dict, object]]:
    """(label, second looks, rule) of every row ``--looks`` prints: each rule on the mirror
    averaged second looks ``ends``, then the shipped rule on the ``plain`` ones."""
    rules = _look_rules()
    return ([(name, ends, rule) for name, rule in rules.items()]
            + [("shipped, the second look without mirror averaging", plain, rules[SHIPPED_RULE])])


def two_looks(pictures: list, boxes: list, weights: str | None) -> tuple[np.ndarray, dict, dict]:
    """The whole car's (B, 24) probabilities, and per picture the second look takes (a boxed
    three-quarter view, :func:`carbody.view.ends.is_three_quarter` of the first look's view) its
    near end's probabilities with mirror averaging (as shipped) and without: two {index: (24,)}."""
    from carbody.view.ends import end_look, second_look_view
    from carbody.view.predict import predict_probabilities, read_image

    pics = [read_image(p) for p in pictures]
    p = np.concatenate([predict_probabilities(pics[i:i + 64], weights, boxes=boxes[i:i + 64], end_looks=False)
                        for i in range(0, len(pics), 64)])
    views = [second_look_view(b, q) for b, q in zip(boxes, p)]
    second = [i for i, v in enumerate(views) if v is not None]
    looks = {}
    for mirror in (True, False):
        q = [predict_probabilities([end_look(pics[i], boxes[i], views[i]) for i in second[k:k + 64]],
                                   weights, mirror_average=mirror, boxes=[boxes[i] for i in second[k:k + 64]],
                                   end_looks=False) for k in range(0, len(second), 64)]
        q = np.concatenate(q) if q else np.zeros((0, p.shape[1]))
        looks[mirror] = dict(zip(second, q))
    return p, looks[True], looks[False]


def voted(p: np.ndarray, ends: dict, rule) -> np.ndarray:
    """(B, 24): each picture with a second look in ``ends`` voted by ``rule``, the rest as read."""
    out = p.copy()
    for i, q in ends.items():
        v = np.asarray(rule(p[i], q), dtype=np.float64)
        out[i] = v / v.sum()
    return out


def facing_read(probs: np.ndarray, view_deg: float) -> float:
    """The share of ``probs`` within 45° of ``view_deg`` against that share and its opposite's:
    how sure the look is that the car faces the ``view_deg`` way rather than the other."""
    from carbody.view.labels import CLASS_ANGLES_DEG, angular_difference

    near = probs[angular_difference(CLASS_ANGLES_DEG, view_deg) <= 45].sum()
    far = probs[angular_difference(CLASS_ANGLES_DEG, view_deg + 180.0) <= 45].sum()
    return float(near / max(near + far, 1e-12))


def main_looks(args) -> int:
    """How the two looks vote (:mod:`carbody.view.ends`), measured where the rule was chosen:
    the real photos (the car's box and the marks' box) and the held-out cars' photo-like renders
    (``--workdir``'s ``test_photo``, rendered there when absent). Also the second look alone, and
    the calibration of each rule on the renders."""
    import torch

    from carbody.view.calibrate import expected_calibration_error
    from carbody.view.dataset import read_manifest, row_box
    from carbody.view.ends import END_LOOK_KEY
    from carbody.view.labels import CLASS_ANGLES_DEG, angular_difference, continuous_estimate
    from carbody.view.predict import keypoint_box, load_classifier

    torch.set_num_threads(1)
    _, meta = load_classifier(args.weights)
    root = Path(args.photos) if args.photos else REAL_PHOTOS
    print(f"weights {args.weights or 'shipped'}; the second look with mirror averaging unless said"
          + ("" if meta.get(END_LOOK_KEY) else "; these weights never learnt the second look (carbody takes "
             "none with them): what it would say"))
    if (root / "keypoints").is_dir():
        photos = real_photo_set(root)
        truth = np.array([p["estimate_deg"] for p in photos])
        print(f"\nreal photos: {len(photos)} from {root} (views estimated by eye, ±10°)")
        print("| box | rule | within ±15° | within ±30° | front/rear confusions | left/right confusions |")
        print("|---|---|---|---|---|---|")
        for label, boxes in (("car's box", [p["parts_box"] for p in photos]),
                             ("marks' box", [keypoint_box(p["marks"]) for p in photos])):
            p, ends, plain = two_looks([ph["image"] for ph in photos], boxes, args.weights)
            for name, looks, rule in look_cases(ends, plain):
                s = real_scores(np.array([continuous_estimate(q) for q in voted(p, looks, rule)]), truth)
                print(f"| {label} | {name} | {s['within15']:.2f} | {s['within30']:.2f} | {s['front_rear']:.2f} | "
                      f"{s['left_right']:.2f} |")
    else:
        print(f"real photos: none at {root} (the shared folder is not here)")
    test_dir = Path(args.workdir or tempfile.mkdtemp(prefix="carbody-view-looks-")) / "test_photo"
    if not (test_dir / "manifest.csv").exists():
        evaluation_set(test_dir, args.count, args.seed, meta["dataset"]["validation_templates"], photo_like=True)
    rows = read_manifest(test_dir)
    boxes = [row_box(r) for r in rows]
    p, ends, plain = two_looks([test_dir / r["file"] for r in rows], boxes, args.weights)
    y = np.array([r["class_index"] for r in rows])
    print(f"\nphoto-like renders of the held-out cars: {len(rows)} from {test_dir}, {len(ends)} given a second look")
    print("| rule | top-1 | within ±15° | front/rear (≥ 150° off) | ECE of the top class |")
    print("|---|---|---|---|---|")
    for name, looks, rule in look_cases(ends, plain):
        q = voted(p, looks, rule)
        s = scores(rows, q)
        print(f"| {name} | {s['top1']:.3f} | {s['within15']:.3f} | {s['front_rear_confusions']:.3f} | "
              f"{expected_calibration_error(q, y):.3f} |")
    print("\nthe three-quarter views given a second look: which way the car faces, read right")
    print("| the car's near end | views | the whole car | the near end alone | the near end, no mirror |")
    print("|---|---|---|---|---|")
    for end, front in (("front", True), ("rear", False)):
        idx = [i for i in ends if (angular_difference(float(rows[i]["theta_deg"]), 0.0) < 90) == front]
        cells = []
        for source in (lambda i: p[i], lambda i: ends[i], lambda i: plain[i]):
            right = [(facing_read(source(i), continuous_estimate(p[i])) > 0.5)
                     == (angular_difference(continuous_estimate(p[i]), float(rows[i]["theta_deg"])) < 90) for i in idx]
            cells.append(f"{np.mean(right):.2f}" if idx else "–")
        print(f"| {end} | {len(idx)} | " + " | ".join(cells) + " |")
    return 0


def recoloured(image: np.ndarray, how: str) -> np.ndarray:
    """The RGB picture with its red pixels (hue within 20° of red, saturation over 0.3) turned to
    their grey (``how="red"``), or all of it grey (``how="grey"``)."""
    import cv2

    grey = np.repeat(cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)[..., None], 3, axis=2)
    if how == "grey":
        return grey
    hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)   # OpenCV's hue runs 0-180
    red = ((hsv[..., 0] <= 10) | (hsv[..., 0] >= 170)) & (hsv[..., 1] > 0.3 * 255)
    return np.where(red[..., None], grey, image)


def recolour_table(photos: list[dict], truth: np.ndarray, weights) -> None:
    """The car's box classified again with the photos' reds turned grey, then all grey: does the
    network tell a car's rear by its red lamps? (A guess of docs/view_classifier.md.)"""
    from carbody.view.labels import continuous_estimate
    from carbody.view.predict import predict_probabilities, read_image

    boxes = [p["parts_box"] for p in photos]
    print("the car's box with the photo's colours changed (--recolour)")
    print("| picture | within ±15° | within ±30° | front/rear confusions | left/right confusions "
          "| photos whose nearer end changed (front/rear) |")
    print("|---|---|---|---|---|---|")
    taken = [read_image(p["image"]) for p in photos]
    base = None
    for label, how in (("as taken", None), ("reds turned grey", "red"), ("all grey", "grey")):
        pictures = [recoloured(im, how) for im in taken] if how else taken
        probs = predict_probabilities(pictures, weights, boxes=boxes)
        pred = np.array([continuous_estimate(q) for q in probs])
        s = real_scores(pred, truth)
        ends = np.cos(np.radians(pred)) > 0              # the front the nearer end
        if base is None:
            base = ends
        changed = "" if how is None else str(int((ends != base).sum()))
        print(f"| {label} | {s['within15']:.2f} | {s['within30']:.2f} | {s['front_rear']:.2f} | "
              f"{s['left_right']:.2f} | {changed} |")


#: Rows of the photo-like ablation, cumulative: (key, label, PhotoLook settings, input px, renders of
#: row). Every row renders the same bodies, split, classes and count (seed 0), 80 % photo-like and
#: 20 % classic, and trains the same schedule; E trains on D's renders. (Row B as measured in
#: docs/view_classifier.md was drawn with tone on as well; the table flags such a row.)
OFF = dict(framing=False, details=False, sharp=False, tone=False)
PHOTO_ROWS = (
    ("A", "earlier photo-like renders (first pass of issue 26)", OFF, 64, "A"),
    ("B", "+ framing: the photo's crop of the car's box, photographer 3-15 m from the car",
     OFF | dict(framing=True), 64, "B"),
    ("C", "+ details: lamps, grilles, intake, mirrors, trims", OFF | dict(framing=True, details=True), 64, "C"),
    ("D", "+ sharp: artefacts at a photo's scale, busy backdrops", OFF | dict(framing=True, details=True, sharp=True),
     64, "D"),
    ("E", "D at 96 px input", OFF | dict(framing=True, details=True, sharp=True), 96, "D"),
    ("F", "+ tone: colours shaded as light, encoded as a camera does", dict(plate_colours=False), 64, "F"),
    ("G", "D at 128 px input (the renders' own size)", OFF | dict(framing=True, details=True, sharp=True), 128, "D"),
)


def photo_row_dataset(work: Path, key: str, look: dict, args) -> Path:
    """The row's training renders (rendered here unless ``work/<key>`` already holds them)."""
    from carbody.view.dataset import Variation, render_dataset
    from carbody.view.photo import PhotoLook

    d = work / key
    if not (d / "manifest.csv").exists():
        render_dataset(d, count=args.count, seed=0, bodies_per_template=3, blends=args.blends, progress=True,
                       vary=Variation(photo=PhotoLook(**{"tone": True} | look), photo_fraction=0.8,
                                      classic_details=False))
    return d


def measure_weights(weights: str, work: Path, photos: list[dict], val_templates: list[str], args) -> dict:
    """Real photos (car's box, marks' box, full photo) and the held-out cars' classic and
    photo-like renders (seed 1234, 480 each) of one weights file."""
    from carbody.view.dataset import read_manifest
    from carbody.view.labels import continuous_estimate
    from carbody.view.predict import keypoint_box, predict_probabilities

    row: dict = {}
    for kind in ("classic", "photo"):
        test_dir = work / f"test_{kind}"
        if not (test_dir / "manifest.csv").exists():
            evaluation_set(test_dir, args.test_count, 1234, val_templates, photo_like=kind == "photo")
        test_rows = read_manifest(test_dir)
        r = scores(test_rows, classify(test_dir, weights, test_rows))
        row |= {f"{kind}_{k}": r[k] for k in ("top1", "within15", "front_rear_confusions")}
    truth = np.array([p["estimate_deg"] for p in photos])
    for label, boxes in (("box", [p["parts_box"] for p in photos]), ("marks", [keypoint_box(p["marks"]) for p in photos]),
                         ("full", [None] * len(photos))):
        if photos:
            pr = predict_probabilities([p["image"] for p in photos], weights, boxes=boxes)
            sc = real_scores(np.array([continuous_estimate(q) for q in pr]), truth)
            row |= {f"{label}_{k}": sc[k] for k in ("within15", "within30", "front_rear", "left_right", "median_err")}
    return row


def main_photo_ablation(args) -> None:
    """One training set per row (same seed, bodies, split and size), the same schedule, each model
    measured on the real photos and on classic and photo-like renders of the held-out cars. Rows
    run in separate processes (``--only B;C``) share ``--workdir``; each row keeps its renders,
    weights (resumable checkpoint) and result in ``WORKDIR/<key>``."""
    import json

    from carbody.view.train import TrainConfig, train_view_classifier

    work = Path(args.workdir or tempfile.mkdtemp(prefix="carbody-view-photo-ablation-"))
    root = Path(args.photos) if args.photos else REAL_PHOTOS
    photos = real_photo_set(root) if (root / "keypoints").is_dir() else []
    if args.measure:
        measure_listed(work, args.measure, photos, args)
    only = [x.strip() for x in args.only.split(";")] if args.only else [k for k, *_ in PHOTO_ROWS]
    if args.table or args.measure:
        only = []
    for key, label, look, size, renders in PHOTO_ROWS:
        if key not in only:
            continue
        d = photo_row_dataset(work, renders, look, args)
        tag = photo_row_tag(args.epochs, size, args.width, args.train_seed)
        w = work / key / f"weights_{tag}.pt"
        result = work / key / f"result_{tag}.json"
        if not w.exists():
            train_view_classifier(d, w, TrainConfig(epochs=args.epochs, threads=1, zoom=True, input_size=size,
                                                    width_mult=args.width, seed=args.train_seed, resume=True),
                                  progress=True)
        from carbody.view.predict import load_classifier

        _, meta = load_classifier(str(w))
        row = measure_weights(str(w), work, photos, meta["dataset"]["validation_templates"], args)
        row |= {"train_s": meta["history"]["seconds"], "val_acc": meta["history"]["val_acc"][-1]}
        result.write_text(json.dumps(row, indent=1))
        print(key, label, row, flush=True)
    print_photo_ablation(work, args.epochs, args.width, args.count, args.blends)


def photo_row_tag(epochs: int, size: int, width: float, seed: int = 0) -> str:
    return f"e{epochs}_{size}px" + ("" if width == 1.0 else f"_w{width:g}") + ("" if seed == 0 else f"_s{seed}")


#: Columns of the photo ablation table: (heading, result keys, decimals).
PHOTO_COLUMNS = (
    ("real car's box ±15° / ±30° / front-rear / left-right", ("box_within15", "box_within30", "box_front_rear",
                                                             "box_left_right"), 2),
    ("marks' box ±15° / ±30°", ("marks_within15", "marks_within30"), 2),
    ("full photo ±15° / ±30°", ("full_within15", "full_within30"), 2),
    ("classic renders top-1 / ±15° / front-rear", ("classic_top1", "classic_within15",
                                                   "classic_front_rear_confusions"), 3),
    ("photo-like renders top-1 / ±15°", ("photo_top1", "photo_within15"), 3),
)


def photo_cells(r: dict) -> str:
    """The table cells of one result (or mean of results)."""
    return " | ".join(" / ".join(f"{r[k]:.{d}f}" for k in keys) for _, keys, d in PHOTO_COLUMNS)


def row_results(work: Path, key: str, epochs: int, size: int, width: float) -> list[dict]:
    """A row's results, one per training seed found in ``work/<key>`` (seed 0 first)."""
    import json
    import re

    base = photo_row_tag(epochs, size, width)
    found = []
    for f in (work / key).glob(f"result_{base}*.json"):
        m = re.fullmatch(re.escape(f"result_{base}") + r"(?:_s(\d+))?\.json", f.name)
        if m:
            found.append((int(m.group(1) or 0), json.loads(f.read_text())))
    return [r for _, r in sorted(found, key=lambda x: x[0])]


def mean_result(results: list[dict]) -> dict:
    return {k: float(np.mean([r[k] for r in results])) for k in results[0]}


def renders_differ(work: Path, renders: str, look: dict) -> list[str]:
    """The photo-like switches with which a row's renders were drawn (their ``dataset.json``) other
    than the row says, as ``"+ tone"`` / ``"- details"``; a switch the file lacks was drawn off
    (it did not exist yet). Empty when they agree or the renders are not there."""
    import json
    from dataclasses import asdict

    from carbody.view.photo import PhotoLook

    f = work / renders / "dataset.json"
    if not f.exists():
        return []
    drawn = json.loads(f.read_text()).get("variation", {}).get("photo") or {}
    meant = asdict(PhotoLook(**{"tone": True} | look))     # as photo_row_dataset draws the row
    return [("+ " if drawn.get(k, False) else "- ") + k for k, v in meant.items() if bool(drawn.get(k, False)) != v]


def print_photo_ablation(work: Path, epochs: int, width: float = 1.0, count: int = 4800, blends: int = 40) -> None:
    """The rows' table (each cell the mean over the training seeds run; a row whose renders were
    drawn otherwise than it says is flagged), the seed-to-seed spread of the rows run with two
    seeds or more, and the weights measured with ``--measure``."""
    import json

    heads = " | ".join(h for h, _, _ in PHOTO_COLUMNS)
    print(f"photo-like ablation ({work}): per row {count} renders (3 bodies a template, {blends} blends, "
          "80 % photo-like), "
          f"MobileNetV2 width {width:g}, {epochs} epochs, 1 thread; each cell the mean over the training seeds run; "
          "real photos: 27, views by eye ±10° (one photo = 0.037); renders: 480 classic and 480 photo-like of the "
          "7 held-out cars (seed 1234)")
    print(f"| training renders | seeds | {heads} | train min |\n|---|---|" + "---|" * len(PHOTO_COLUMNS) + "---|")
    spread = []
    for key, label, look, size, renders in PHOTO_ROWS:
        results = row_results(work, key, epochs, size, width)
        if not results:
            continue
        differ = renders_differ(work, renders, look)
        if differ:
            label += f" (**renders drawn with {', '.join(differ)}**)"
        print(f"| {key}: {label} | {len(results)} | {photo_cells(mean_result(results))} | "
              f"{np.mean([r['train_s'] for r in results]) / 60:.0f} |")
        if len(results) > 1:
            spread.append((key, {k: float(np.ptp([r[k] for r in results])) for k in results[0]}))
    if spread:
        print("\nseed to seed (the same renders trained with each training seed): largest minus smallest")
        print(f"| row | {heads} |\n|---|" + "---|" * len(PHOTO_COLUMNS))
        for key, r in spread:
            print(f"| {key} | {photo_cells(r)} |")
    measured = sorted((work / "measured").glob("*.json"))
    if measured:
        print("\nweights measured on the same photos and renders (--measure)")
        print(f"| weights | {heads} |\n|---|" + "---|" * len(PHOTO_COLUMNS))
        for f in measured:
            r = json.loads(f.read_text())
            print(f"| {r.get('label', f.stem)} | {photo_cells(r)} |")


def measure_listed(work: Path, specs: list[str], photos: list[dict], args) -> None:
    """Measure ``LABEL=WEIGHTS`` files like the rows (``work/measured/<label>.json``); the held-out
    cars are the ablation's (row D's data set), so every file is measured on the same renders."""
    import json
    import re

    if not (work / "D" / "dataset.json").exists():
        raise SystemExit(f"--measure needs row D's renders in {work / 'D'} (their held-out cars)")
    val = json.loads((work / "D" / "dataset.json").read_text())["validation_templates"]
    for spec in specs:
        label, _, weights = spec.partition("=")
        if not weights:
            raise SystemExit(f"--measure wants LABEL=WEIGHTS, got {spec!r}")
        row = {"label": label, "weights": weights} | measure_weights(weights, work, photos, val, args)
        out = work / "measured" / (re.sub(r"[^A-Za-z0-9_.-]+", "_", label) + ".json")
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(row, indent=1))
        print(label, row, flush=True)


#: The plain sweep's paints (the shipped test's red, a blue and a silver) and views.
SWEEP_PAINTS = {"red": (0.75, 0.1, 0.1), "blue": (0.1, 0.2, 0.6), "silver": (0.6, 0.62, 0.65)}
SWEEP_ELEVATIONS = (5, 10, 20)


def main_plain_sweep(args) -> int:
    """Every held-out car as ``tests/test_view_shipped.py`` draws it (its body and wheels, no
    lamps or grille, orthographic, 85 % fill, a plain backdrop) at all 24 classes × 3 elevations,
    in three paints: the share within ±15° per weights file (``--measure``, else the shipped)."""
    from carbody.render import Look, Scene, tessellate
    from carbody.surface import build_body
    from carbody.templates import load_templates
    from carbody.view.dataset import wheel_meshes
    from carbody.view.labels import angular_difference
    from carbody.view.predict import load_classifier, predict_view

    weights = dict(m.split("=", 1) for m in args.measure) or {"shipped": None}
    _, meta = load_classifier(next(iter(weights.values())))
    held_out = meta["dataset"]["validation_templates"]
    templates = load_templates()
    hits = {(w, p): [] for w in weights for p in SWEEP_PAINTS}
    for name in held_out:
        row, wf = next((r, w) for r, w in templates if r["name"] == name)
        scene = Scene(tessellate(build_body(wf, check=False))
                      + wheel_meshes(wf.control_points, float(row["tyre_radius_mm"])), size=(160, 120))
        for paint, rgb in SWEEP_PAINTS.items():
            look = Look(paint=rgb, background=(0.85, 0.87, 0.9),
                        colours={"tyre": (0.05, 0.05, 0.05), "rim": (0.6, 0.6, 0.6)})
            for theta in range(0, 360, 15):
                for elevation in SWEEP_ELEVATIONS:
                    mirrored = theta > 180
                    img = scene.render(360 - theta if mirrored else theta, elevation, look=look, distance=None,
                                       fill=0.85)
                    img = img[:, ::-1].copy() if mirrored else img
                    for label, w in weights.items():
                        p = predict_view(img, weights=w)
                        hits[label, paint].append(angular_difference(p.theta_deg, theta) <= 15)
    n = len(held_out) * 24 * len(SWEEP_ELEVATIONS)
    print(f"plain sweep: {len(held_out)} held-out cars × 24 views × {len(SWEEP_ELEVATIONS)} elevations = {n} "
          f"renders per paint; share within ±15°")
    print("| weights | " + " | ".join(SWEEP_PAINTS) + " |\n|---|" + "---|" * len(SWEEP_PAINTS))
    for label in weights:
        print(f"| {label} | " + " | ".join(f"{np.mean(hits[label, p]):.3f}" for p in SWEEP_PAINTS) + " |")
    return 0


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
    ap.add_argument("--only", default=None, help="ablation: comma-separated variant names to run (--photo-ablation: separated by ';')")
    ap.add_argument("--photo-like", action="store_true", help="evaluate on photo-like renders (default classic)")
    ap.add_argument("--templates", default=None,
                    help="comma-separated templates to render for the evaluation (default: the weights' held-out cars)")
    ap.add_argument("--keep", default=None, help="render the evaluation set into this folder (reuse with --dataset)")
    ap.add_argument("--photo-ablation", action="store_true",
                    help="ablation of the photo-like renders, measured on the real photos (see PHOTO_ROWS)")
    ap.add_argument("--blends", type=int, default=40, help="photo ablation: blended bodies per training set")
    ap.add_argument("--width", type=float, default=1.0, help="photo ablation: MobileNetV2 width multiplier")
    ap.add_argument("--train-seed", type=int, default=0, help="photo ablation: training seed (a replicate's)")
    ap.add_argument("--measure", action="append", default=[], metavar="LABEL=WEIGHTS",
                    help="photo ablation (and --plain-sweep): measure this weights file on the rows' photos and "
                         "renders (repeatable)")
    ap.add_argument("--table", action="store_true", help="photo ablation: print the table of what is measured")
    ap.add_argument("--plain-sweep", action="store_true",
                    help="the held-out cars as the shipped weights' test draws them, every view, three paints "
                         "(--measure LABEL=WEIGHTS to compare files)")
    ap.add_argument("--real", action="store_true", help="classify the real photos of ../shared/realphotos")
    ap.add_argument("--photos", default=None, help="--real: the photo folder (default ../shared/realphotos)")
    ap.add_argument("--verbose", action="store_true", help="--real: one row per photo")
    ap.add_argument("--recolour", action="store_true",
                    help="--real: also classify the car's box with its reds, then all of it, turned grey")
    ap.add_argument("--looks", action="store_true",
                    help="how the two looks vote, on the real photos and the held-out cars' photo-like renders "
                         "(--workdir keeps the renders)")
    ap.add_argument("--speed", action="store_true",
                    help="inference time per picture as carbody view --box runs it (exported network, ONNX Runtime)")
    ap.add_argument("--repeats", type=int, default=200, help="--speed: timed calls per setting")
    ap.add_argument("--threads", type=int, default=1,
                    help="--speed: OpenCV's and the network's threads (default 1, as a batch worker; the core count as `carbody view`)")
    args = ap.parse_args()
    os.environ.setdefault("CARBODY_CACHE_DIR", tempfile.mkdtemp(prefix="carbody-bench-"))
    if args.real:
        return main_real(args)
    if args.looks:
        return main_looks(args)
    if args.speed:
        return main_speed(args)
    if args.plain_sweep:
        return main_plain_sweep(args)
    if args.photo_ablation:
        if args.count == 480:
            args.count = 4800
        if args.test_count == 2400:
            args.test_count = 480
        if args.epochs == 25:
            args.epochs = 40
        return main_photo_ablation(args)
    if args.ablation:
        if args.count == 480:
            args.count = 1200
        main_ablation(args)
    else:
        main_eval(args)


if __name__ == "__main__":
    sys.exit(main())
