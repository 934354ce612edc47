"""Can a network trained on our renders alone put the keypoints where a person clicks them on a
real photo? A probe for issue 27's clicks, not part of the pipeline.

The guided page (:mod:`carbody.annotate`) counts one action per mark: a click, a drag or an
accepted ghost. On the real photos the best order of the hand marks still needs 61–76 % of them
to reach the hand fit (``bench_annotate.py --oracle``), so half the clicks needs one action that
places several marks from the photo's own evidence. This probe measures whether such evidence
can come from a keypoint detector trained on renders alone:

1. **Renders** (``WORKDIR/renders``): photo-like renders of the library's 33 templates, one
   expansion of each and 30 blends, as ``probe_tyres.py`` draws them (the same bodies, shots and
   varied rims), each with the photo position of every keypoint the view shows
   (:func:`carbody.fit.visibility.visible_keypoints` at the render's camera). A mirrored shot
   swaps each keypoint with its ``_right`` twin.
2. **A U-Net** (``WORKDIR/keypoints.pt``): the car's box, squared and scaled to
   :data:`INPUT_PX`, in; one heat map per keypoint name (62) out, a Gaussian of
   :data:`SIGMA_PX` at each keypoint shown, trained with the penalty-reduced focal loss of
   CenterNet, random margins, shifts, mirroring (names swapped), exposure, white balance, blur
   and noise.
3. **The real photos** (``../shared/realphotos``; skipped where absent): the box of the hand
   marks, taken 15 % of its height lower, goes in (``probe_tyres.marks_box``). Each hand mark's
   own heat map gives its peak (refined to a fraction of a pixel by the 3×3 centroid round it)
   and the peak's height. Per photo and in all: the distance of the peak from the hand mark, %
   of S (the car's image size, as ``bench_real_photos.py`` takes it), and the share of marks
   within 1, 2 and 3 % of S. The page's ghosts user drags a ghost more than 1 % off, and two
   people's clicks lie about 1–1.5 % apart: a detection within 1 % is as good as a click.

    python benchmarks/probe_keypoints.py --workdir W [--images-per-body 20] [--epochs 14] \
        [--threads 2] [--seed 0] [--held-out N] [--flip] [--json FILE]

Each step is skipped when its output is already in the work folder. Nothing here is shipped, and
no real photo is used in training.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_real_photos as real  # noqa: E402  (the photos, their size S)
import probe_tyres as tyres  # noqa: E402  (the bodies, rims, crops and the U-Net)

#: The network's input side, pixels (the car's box fills about 80 % of it).
INPUT_PX = 192
#: The stem's channels (a stride-2 convolution: the heat maps are half the input's side) and the
#: U-Net's at its four scales.
STEM, CHANNELS = 16, (24, 48, 64, 96)
#: The heat maps' side, pixels.
MAP_PX = INPUT_PX // 2
#: The heat maps' Gaussian, map pixels.
SIGMA_PX = 1.5
#: The shares of S a detection is counted within.
WITHIN_PCT = (1.0, 2.0, 3.0)


def keypoint_names() -> list[str]:
    """The 62 keypoint names (both halves), in id order: the heat maps' order."""
    from carbody.fit.visibility import keypoint_slots
    from carbody.topology import load_topology

    return list(keypoint_slots(load_topology()))


def twin(name: str, names: list[str]) -> str:
    """The keypoint a mirrored picture shows at ``name``'s place: its other half's (a central
    keypoint its own)."""
    if name.endswith("_right"):
        return name[: -len("_right")]
    return f"{name}_right" if f"{name}_right" in names else name


def render(out: Path, images_per_body: int, max_bodies: int | None = None, seed: int = tyres.SEED) -> int:
    """Photo-like renders and their keypoints into ``out`` (module docstring, step 1), of the
    first ``max_bodies`` bodies (None: all), drawn from ``seed`` (another: other expansions,
    blends and shots): the count."""
    import cv2

    import carbody.view.dataset as dataset
    from carbody.camera import View
    from carbody.fit.visibility import keypoint_slots, visible_keypoints
    from carbody.topology import load_topology

    slots = keypoint_slots(load_topology())
    names = list(slots)
    out.mkdir(parents=True, exist_ok=True)
    count = 0
    for b, spec, _, scene, vary in tyres.photo_scenes(max_bodies, seed=seed):
        cp = np.asarray(spec.control_points_mm, float)
        points = np.array([cp[s.point_index] * s.sign for s in slots.values()])
        lo, hi = scene.bounds
        centre, car_length = (lo + hi) / 2, float(hi[1] - lo[1])
        for i in range(images_per_body):
            rng = np.random.default_rng([seed, b, i])
            shot, image = dataset.shoot_photo(scene, spec, int(rng.integers(0, dataset.N_CLASSES)), rng, vary)
            uv = scene.project(points)
            view = View(shot.render_theta_deg, shot.elevation_deg, shot.roll_deg,
                        distance=shot.distance_lengths * car_length, aim=tuple(centre))
            seen = set(visible_keypoints(view, cp))
            marks = {}
            for name, (u, v) in zip(names, uv):
                if name in seen and 0 <= u < tyres.RENDER_PX and 0 <= v < tyres.RENDER_PX:
                    if shot.mirrored:
                        name, u = twin(name, names), tyres.RENDER_PX - u
                    marks[name] = [round(float(u), 2), round(float(v), 2)]
            stem = out / f"{spec.body_id}_{i:03d}"
            cv2.imwrite(f"{stem}.jpg", image[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 92])
            Path(f"{stem}.json").write_text(json.dumps({"box": shot.box, "keypoints": marks}))
            count += 1
    return count


def network():
    """The stem and U-Net (module docstring, step 2): (n, 3, s, s) normalised RGB → (n, 62, s / 2,
    s / 2) logits."""
    from torch import nn

    stem = nn.Sequential(nn.Conv2d(3, STEM, 3, stride=2, padding=1, bias=False), nn.BatchNorm2d(STEM),
                         nn.ReLU(inplace=True))
    return nn.Sequential(stem, tyres.network(CHANNELS, len(keypoint_names()), inputs=STEM))


def heat_maps(points: dict[str, tuple[float, float]], names: list[str], side: int) -> np.ndarray:
    """(len(names), side, side) float32: a Gaussian of :data:`SIGMA_PX` at each of ``points``
    (map px), exactly 1 at its nearest pixel; 0 for a name not among them."""
    maps = np.zeros((len(names), side, side), np.float32)
    grid = np.arange(side, dtype=np.float32)
    for name, (u, v) in points.items():
        k = names.index(name)
        cu, cv = u - 0.5, v - 0.5  # pixel centres at integer + 0.5
        if not (0 <= round(cu) < side and 0 <= round(cv) < side):
            continue
        gu, gv = np.exp(-((grid - cu) ** 2) / (2 * SIGMA_PX ** 2)), np.exp(-((grid - cv) ** 2) / (2 * SIGMA_PX ** 2))
        maps[k] = np.outer(gv, gu)
        maps[k, int(round(cv)), int(round(cu))] = 1.0
    return maps


def training_pair(image: np.ndarray, marks: dict, box, names: list[str], rng: np.random.Generator,
                  strong: bool = False):
    """(input (3, s, s), target (62, s, s)) of one render, randomly cropped, mirrored and spoilt;
    ``strong``: also turned ±8° and scaled ±10 %, blurred more, partly covered, grey one time in
    ten and saved as a JPEG of quality 30–90 (``--augment strong``)."""
    import cv2
    import torch

    crop, M = tyres.square_crop(image, box, rng.uniform(0.05, 0.35), rng.uniform(-0.06, 0.06, 2), side=INPUT_PX)
    if strong:  # a turn and a scale about the crop's centre, applied to the photo's map too
        R = cv2.getRotationMatrix2D((INPUT_PX / 2, INPUT_PX / 2), rng.uniform(-8, 8), rng.uniform(0.9, 1.1))
        M = (np.vstack([R, [0, 0, 1]]) @ np.vstack([M, [0, 0, 1]]))[:2].astype(np.float32)
        crop = cv2.warpAffine(image, M, (INPUT_PX, INPUT_PX), flags=cv2.INTER_AREA, borderMode=cv2.BORDER_REPLICATE)
    points = {n: tuple(M[:, :2] @ np.asarray(p, np.float32) + M[:, 2]) for n, p in marks.items()}
    if rng.random() < 0.5:
        crop = crop[:, ::-1]
        points = {twin(n, names): (INPUT_PX - u, v) for n, (u, v) in points.items()}
    points = {n: (u * MAP_PX / INPUT_PX, v * MAP_PX / INPUT_PX) for n, (u, v) in points.items()}
    x = crop.astype(np.float32) * rng.uniform(0.7, 1.3) + rng.uniform(-25, 25)  # exposure
    x = x * rng.uniform(0.85, 1.15, 3)                                          # white balance
    if rng.random() < (0.4 if strong else 0.3):
        x = cv2.GaussianBlur(x, (0, 0), rng.uniform(0.3, 1.5 if strong else 1.0))
    if strong:
        for _ in range(rng.integers(0, 3)):  # something in front of the car: a pole, a bush, a person
            w, h = (rng.uniform(0.05, 0.3, 2) * INPUT_PX).astype(int)
            u, v = rng.integers(0, INPUT_PX - w), rng.integers(0, INPUT_PX - h)
            x[v:v + h, u:u + w] = rng.uniform(0, 255, 3)
        if rng.random() < 0.1:
            x[:] = x.mean(axis=2, keepdims=True)
    x = np.clip(x + rng.normal(0, rng.uniform(0, 6), x.shape), 0, 255).astype(np.uint8)
    if strong:
        x = cv2.imdecode(cv2.imencode(".jpg", x, [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(30, 91))])[1],
                         cv2.IMREAD_UNCHANGED).reshape(x.shape)
    return tyres.as_input(x), torch.from_numpy(heat_maps(points, names, MAP_PX))


def focal_loss(logits, target):
    """CenterNet's penalty-reduced focal loss of heat-map ``logits`` against ``target`` (peaks at
    exactly 1), per peak."""
    import torch
    from torch.nn import functional as F

    p = torch.sigmoid(logits).clamp(1e-4, 1 - 1e-4)
    peak = target.eq(1.0).float()
    positive = -(F.logsigmoid(logits) * (1 - p) ** 2 * peak).sum()
    negative = -(F.logsigmoid(-logits) * p ** 2 * (1 - target) ** 4 * (1 - peak)).sum()
    return (positive + negative) / peak.sum().clamp(min=1.0)


def train(renders: Path, out: Path, epochs: int, seed: int = 0, strong: bool = False) -> list[float]:
    """Train the U-Net on ``renders`` (module docstring, step 2; ``strong``: the stronger spoiling
    of :func:`training_pair`), save it to ``out``: the mean loss of each epoch."""
    import cv2
    import torch

    torch.manual_seed(seed)
    names = keypoint_names()
    data = []
    for f in sorted(renders.glob("*.jpg")):
        meta = json.loads(f.with_suffix(".json").read_text())
        data.append((cv2.imread(str(f))[..., ::-1].copy(), meta["keypoints"], meta["box"]))
    net = network()
    with torch.no_grad():  # start every map near "no keypoint here" (CenterNet's prior)
        net[1].head.bias.fill_(-4.6)

    def batch_loss(net, items, rng):
        xs, ys = zip(*[training_pair(*item, names, rng, strong) for item in items])
        return focal_loss(net(torch.stack(xs)), torch.stack(ys))

    return tyres.fit_network(net, data, epochs, seed, batch_loss, out)


def trained_network(weights: Path):
    """The U-Net with the weights saved at ``weights``, ready to read photos."""
    import torch

    net = network()
    net.load_state_dict(torch.load(weights))
    return net.eval()


def peaks(maps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((k, 2) map px, (k,) height): each heat map's highest pixel, refined to a fraction of a
    pixel by the parabola through the logarithms of it and its two neighbours each way (exact for
    a Gaussian; pixel centres at integer + 0.5)."""
    k, side, _ = maps.shape
    flat = maps.reshape(k, -1).argmax(1)
    rows, cols = np.divmod(flat, side)
    height = maps.reshape(k, -1)[np.arange(k), flat]
    logs = np.log(np.maximum(np.pad(maps, ((0, 0), (1, 1), (1, 1)), mode="edge"), 1e-12))
    j, r, c = np.arange(k), rows + 1, cols + 1

    def offset(before: np.ndarray, at: np.ndarray, after: np.ndarray) -> np.ndarray:
        curve = before - 2 * at + after
        return np.where(curve < -1e-9, np.clip(0.5 * (before - after) / np.minimum(curve, -1e-9), -0.5, 0.5), 0.0)

    du = offset(logs[j, r, c - 1], logs[j, r, c], logs[j, r, c + 1])
    dv = offset(logs[j, r - 1, c], logs[j, r, c], logs[j, r + 1, c])
    return np.stack([cols + du + 0.5, rows + dv + 0.5], axis=1), height


def detect(net, rgb: np.ndarray, box, flip: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """((62, 2) photo px, (62,) peak height) of every keypoint name in a photo, reading the square
    round ``box`` (margin :data:`probe_tyres.MARGIN`); with ``flip`` each heat map is averaged
    with its twin's read in the mirrored crop."""
    import torch

    crop, M = tyres.square_crop(rgb, box, tyres.MARGIN, side=INPUT_PX)
    with torch.no_grad():
        x = tyres.as_input(crop)[None]
        maps = torch.sigmoid(net(x))[0].numpy()
        if flip:
            names = keypoint_names()
            mirrored = torch.sigmoid(net(torch.flip(x, [3])))[0].numpy()[:, :, ::-1]
            maps = (maps + mirrored[[names.index(twin(n, names)) for n in names]]) / 2
    uv, height = peaks(np.ascontiguousarray(maps))
    uv *= INPUT_PX / MAP_PX
    A, t = M[:, :2].astype(float), M[:, 2].astype(float)
    return (uv - t) @ np.linalg.inv(A).T, height


def measure(net, data: Path, flip: bool = False) -> list[dict]:
    """One row per real photo (module docstring, step 3): per hand mark its distance from the
    detection (:func:`detect`, ``flip`` passed on), % of S, and the peak's height."""
    import cv2

    names = keypoint_names()
    rows = []
    for photo in real.load_photos(data):
        rgb = cv2.imread(str(photo.image))[..., ::-1].copy()
        size, _ = real.car_image_size(photo)
        uv, height = detect(net, rgb, tyres.marks_box(photo), flip)
        marks = {n: p for n, p in photo.meta["keypoints"].items() if n in names}
        per_mark = {n: (100.0 * float(np.linalg.norm(uv[names.index(n)] - np.asarray(p, float))) / size,
                        float(height[names.index(n)])) for n, p in marks.items()}
        rows.append({"photo": photo.name, "marks": len(marks), "per_mark": per_mark})
    return rows


def measure_renders(net, renders: Path) -> list[float]:
    """Each keypoint's distance from its detection, % of the larger side of the car's box in the
    picture (S, as on the real photos), over the renders in ``renders``."""
    import cv2

    names, distances = keypoint_names(), []
    for f in sorted(renders.glob("*.jpg")):
        meta = json.loads(f.with_suffix(".json").read_text())
        points = meta["keypoints"]
        if not points:
            continue
        uv, _ = detect(net, cv2.imread(str(f))[..., ::-1].copy(), meta["box"])
        x0, y0, x1, y1 = meta["box"]
        size = max(x1 - x0, y1 - y0)
        distances += [100.0 * float(np.linalg.norm(uv[names.index(n)] - np.asarray(p))) / size
                      for n, p in points.items()]
    return distances


def within(distances: list[float]) -> dict[float, float]:
    """{% of S: the share of ``distances`` within it}."""
    return {w: sum(d <= w for d in distances) / max(1, len(distances)) for w in WITHIN_PCT}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workdir", type=Path, required=True, help="renders and weights go here (reused)")
    parser.add_argument("--data", type=Path, default=real.DATA, help="the real photos")
    parser.add_argument("--images-per-body", type=int, default=20)
    parser.add_argument("--max-bodies", type=int, default=None, help="render only the first N bodies")
    parser.add_argument("--epochs", type=int, default=14)
    parser.add_argument("--threads", type=int, default=2, help="torch's threads for training")
    parser.add_argument("--seed", type=int, default=0, help="the training's seed (the renders' is fixed)")
    parser.add_argument("--held-out", type=int, default=0, metavar="N",
                        help="also measure on N renders of other bodies and shots (WORKDIR/held_out)")
    parser.add_argument("--augment", choices=("plain", "strong"), default="plain",
                        help="the training's spoiling: exposure, colour, blur and noise, or also turns, scales, "
                             "cover, grey and JPEG ('strong')")
    parser.add_argument("--flip", action="store_true",
                        help="average each real photo's heat maps with its mirror's (names swapped)")
    parser.add_argument("--json", type=Path, help="also write the rows and summary here")
    args = parser.parse_args(argv)
    import torch

    torch.set_num_threads(args.threads)
    renders, weights = args.workdir / "renders", args.workdir / "keypoints.pt"
    start = time.perf_counter()
    if not renders.is_dir():
        count = render(renders, args.images_per_body, args.max_bodies)
        print(f"rendered {count} pictures in {time.perf_counter() - start:.0f} s", flush=True)
    if not weights.is_file():
        start = time.perf_counter()
        train(renders, weights, args.epochs, args.seed, args.augment == "strong")
        print(f"trained in {time.perf_counter() - start:.0f} s", flush=True)
    net = trained_network(weights)
    held_out = None
    if args.held_out:
        folder = args.workdir / "held_out"
        if not folder.is_dir():
            render(folder, 1, args.held_out, seed=tyres.SEED + 1)
        held_out = measure_renders(net, folder)
        print(f"held-out renders: {len(held_out)} keypoints, median distance {statistics.median(held_out):.1f} % of "
              "S; " + ", ".join(f"{s:.0%} within {w:g} %" for w, s in within(held_out).items()))
    if not (args.data / "keypoints").is_dir():
        print(f"no real photos at {args.data}: nothing to measure")
        return 0
    rows = measure(net, args.data, args.flip)
    print("\n| photo | hand marks | median distance, % of S | " + " | ".join(f"within {w:g} %" for w in WITHIN_PCT)
          + " |\n|---|---|---|" + "---|" * len(WITHIN_PCT))
    for r in rows:
        d = [v[0] for v in r["per_mark"].values()]
        print(f"| {r['photo']} | {r['marks']} | {statistics.median(d):.1f} | "
              + " | ".join(f"{s:.0%}" for s in within(d).values()) + " |")
    every = [v for r in rows for v in r["per_mark"].values()]
    distances = [d for d, _ in every]
    confident = [d for d, h in every if h >= 0.5]
    summary = {"photos": len(rows), "marks": len(distances), "median_pct": statistics.median(distances),
               "within": within(distances), "confident": len(confident),
               "confident_median_pct": statistics.median(confident) if confident else None,
               "confident_within": within(confident),
               "held_out_median_pct": statistics.median(held_out) if held_out else None,
               "held_out_within": within(held_out) if held_out else None}
    print(f"\n{len(distances)} hand marks on {len(rows)} photos: median distance {summary['median_pct']:.1f} % of S; "
          + ", ".join(f"{s:.0%} within {w:g} %" for w, s in summary["within"].items()))
    if confident:
        print(f"peaks of 0.5 or more: {len(confident)} marks, median {summary['confident_median_pct']:.1f} %; "
              + ", ".join(f"{s:.0%} within {w:g} %" for w, s in summary["confident_within"].items()))
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "summary": summary}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
