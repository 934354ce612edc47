"""Can a network trained on our renders alone find the tyres a real photo shows? A probe for
issue 24's wheel centres, not part of the pipeline.

The people drew each wheel the photo shows, tyre and rim, where it is visible. The hub search
(:mod:`carbody.fit.wheels`) looks for concentric circles where the fitted car puts a wheel; it
misses wheels far from there and takes a headlamp or a rim's upper part for a hub. This probe
asks whether the photo's wheels can be found without the fitted camera, as the people drew them:

1. **Renders** (``WORKDIR/renders``): photo-like renders of the library's 33 templates, one
   expansion of each and 30 blends (:func:`carbody.view.dataset.shoot_photo`, every
   :class:`~carbody.view.photo.PhotoLook` switch on, 384 px), each with a mask of the wheels'
   visible pixels. The mask is a second render of the same shot with the wheels white and all
   else black, so the body hides what it hides in the photo. The data set's wheel is a black
   tyre round a flat grey disc; unless ``--plain-wheels``, each rim is made more like a real one
   (:func:`varied_rims`): 4–10 spokes of varied width over a dark gap, or a disc, grey or in the
   car's paint (white, black, silver most of all).
2. **A small U-Net** (``WORKDIR/tyres.pt``, about 240 000 weights): the car's box, squared and
   scaled to 160 px, in; each pixel's chance of being a wheel out. Trained with random margins,
   shifts, mirroring, exposure, white balance, blur and noise.
3. **The real photos** (``../shared/realphotos``; skipped where absent): the box of the marks,
   taken 15 % of its height lower (people mark no tyre's bottom), goes in; with ``--box
   fitted``, the box of the ``--fitted`` car's control points, where that run made a body.
   Each pixel over 0.5 is a wheel's; each connected part larger than 3 (1 % of S)² is a wheel found (S: the car's
   image size, as ``bench_real_photos.py`` takes it). Per photo: the IoU of those pixels with
   the people's wheel polygons; the annotated wheels matched one-to-one to the wheels found,
   least total distance (``bench_real_photos.wheel_matches``), and the mean distance of their
   centroids, % of S. That is the like-for-like measure's own kind (visible against visible).
4. **With the fit** (``--fitted DIR``, a ``bench_real_photos.py --out`` folder): the like-for-like
   measure of the fitted car's visible tyres (``bench_real_photos.visible_tyre_centres``), then
   again with each tyre moved onto the centroid of the nearest wheel found, where one lies
   within ``--near`` % of S (each value given), and its hub with it; and both by hub, the
   headline measure. No fit can follow the network's wheels further than that.

    python benchmarks/probe_tyres.py --workdir W [--images-per-body 20] [--epochs 14] [--threads 2] \
        [--seed 0] [--plain-wheels] [--fitted DIR [--near 3 5] [--box marks|fitted]] [--json FILE]

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

import bench_real_photos as real  # noqa: E402  (the photos, their wheels, the matching)

#: The renders' side (the car fills 60–78 % of it) and the network's input side, pixels.
RENDER_PX, INPUT_PX = 384, 160
#: The U-Net's channels at its four scales.
CHANNELS = (12, 24, 48, 64)
#: The marks' box is taken this share of its height lower: no mark sits at a tyre's bottom.
BELOW_MARKS = 0.15
#: The square crop's margin round the car's box (at run time; training draws 5–35 %).
MARGIN = 0.25
#: The mesh names whose visible pixels are a wheel's (``wheel_paint``: a rim in the car's paint).
WHEEL_PARTS = ("tyre", "rim", "wheel_paint")
#: The renders' seed: the bodies, the blends, the rims and every shot follow from it.
SEED = 7


def varied_rims(meshes: list, rng: np.random.Generator) -> list:
    """``meshes`` with each flat ``rim`` disc of :func:`carbody.view.dataset.wheel_meshes` made
    more like a real rim: a solid disc one time in five, else a lip, a hub and 4–10 spokes over a
    dark gap (named ``tyre``: it takes the tyre's black). Each wheel's rim is grey (``rim``) or in
    the car's paint (``wheel_paint``), four times in ten."""
    from carbody.render.mesh import FaceMesh

    def disc(x: float, yc: float, zc: float, r0: float, r1: float, segments: int = 40):
        a = np.linspace(0, 2 * np.pi, segments, endpoint=False)
        ring = lambda r: np.c_[np.full(segments, x), yc + r * np.cos(a), zc + r * np.sin(a)]  # noqa: E731
        i, j = np.arange(segments), (np.arange(segments) + 1) % segments
        return np.vstack([ring(r0), ring(r1)]), np.r_[np.c_[i, i + segments, j], np.c_[j, i + segments, j + segments]]

    out = []
    for mesh in meshes:
        if mesh.name != "rim":
            out.append(mesh)
            continue
        centre = mesh.vertices[-1]
        r = float(np.linalg.norm(mesh.vertices[0, 1:] - centre[1:]))
        x, yc, zc, side = float(mesh.vertices[0, 0]), float(centre[1]), float(centre[2]), float(np.sign(centre[0]))
        name = "wheel_paint" if rng.random() < 0.4 else "rim"
        if rng.random() < 0.2:
            out.append(FaceMesh(name, mesh.vertices, mesh.triangles))
            continue
        out.append(FaceMesh("tyre", *disc(x - 2.0 * side, yc, zc, 0.0, r)))           # the gap behind the spokes
        out.append(FaceMesh(name, *disc(x, yc, zc, rng.uniform(0.8, 0.92) * r, r)))    # the lip
        out.append(FaceMesh(name, *disc(x + side, yc, zc, 0.0, rng.uniform(0.12, 0.25) * r)))  # the hub
        n, phase = int(rng.integers(4, 11)), rng.uniform(0, 2 * np.pi)
        inner, outer = rng.uniform(0.03, 0.08) * r, rng.uniform(0.04, 0.5) * r * np.pi / n
        for k in range(n):
            a = phase + 2 * np.pi * k / n
            along, across = np.array([np.cos(a), np.sin(a)]), np.array([-np.sin(a), np.cos(a)])
            corners = [0.15 * r * along - inner * across, 0.15 * r * along + inner * across,
                       0.9 * r * along + outer * across, 0.9 * r * along - outer * across]
            v = np.array([[x + 0.5 * side, yc + c[0], zc + c[1]] for c in corners])
            out.append(FaceMesh(name, v, np.array([[0, 1, 2], [0, 2, 3]])))
    return out


def photo_scenes(max_bodies: int | None = None, plain_wheels: bool = False, seed: int = SEED):
    """(body index, :class:`~carbody.view.dataset.BodySpec`, meshes, scene, the photo look's
    variation) of each body that surfaces (module docstring, step 1): the library's templates, one
    expansion of each and 30 blends drawn from ``seed``, the first ``max_bodies`` (None: all),
    the rims varied unless ``plain_wheels``. While it runs the data set draws at
    :data:`RENDER_PX`."""
    import carbody.view.dataset as dataset
    from carbody.library import load_library
    from carbody.render import Scene
    from carbody.templates import load_templates
    from carbody.view.photo import PhotoLook

    library, rows = load_library(), [row for row, _ in load_templates()]
    bodies = dataset.choose_bodies(library, rows, 2, seed)
    bodies += dataset.blend_bodies(library, rows, sorted({b.template for b in bodies}), 30, seed)
    vary = dataset.Variation(photo=PhotoLook(), photo_fraction=1.0)
    size, dataset.IMAGE_SIZE = dataset.IMAGE_SIZE, RENDER_PX  # the backdrop and ground are drawn at it
    try:
        for b, spec in enumerate(bodies[:max_bodies]):
            meshes, _ = dataset.surfaced_meshes(spec, vary=vary, seed=b)
            if meshes is None:
                continue
            if not plain_wheels:
                meshes = varied_rims(meshes, np.random.default_rng([seed, 5, b]))
            yield b, spec, meshes, Scene(meshes, size=(RENDER_PX, RENDER_PX), antialias=2), vary
    finally:
        dataset.IMAGE_SIZE = size  # the data set's own renders keep theirs


def render(out: Path, images_per_body: int, max_bodies: int | None = None, plain_wheels: bool = False) -> int:
    """Photo-like renders and their wheel masks into ``out`` (module docstring, step 1), of the
    first ``max_bodies`` bodies (None: all), the rims varied unless ``plain_wheels``: the count."""
    import cv2

    import carbody.view.dataset as dataset
    from carbody.render import Look

    out.mkdir(parents=True, exist_ok=True)
    count = 0
    for b, spec, meshes, scene, vary in photo_scenes(max_bodies, plain_wheels):
        white = {name: (1.0, 1.0, 1.0) if name in WHEEL_PARTS else (0.0, 0.0, 0.0) for name in {m.name for m in meshes}}
        label = Look(paint=(0, 0, 0), glass=(0, 0, 0), colours=white, background=(0.0, 0.0, 0.0),
                     light_intensity=0.0, ambient=1.0, diffuse=0.0, specular=0.0)
        lo, hi = scene.bounds
        car_length = float(hi[1] - lo[1])
        for i in range(images_per_body):
            rng = np.random.default_rng([SEED, b, i])
            shot, image = dataset.shoot_photo(scene, spec, int(rng.integers(0, dataset.N_CLASSES)), rng, vary)
            mask = scene.render(shot.render_theta_deg, shot.elevation_deg, shot.roll_deg, look=label,
                                distance=shot.distance_lengths * car_length, fill=shot.fill, offset=shot.offset)
            mask = (mask[..., 0] > 127).astype(np.uint8) * 255
            stem = out / f"{spec.body_id}_{i:03d}"
            cv2.imwrite(f"{stem}.jpg", image[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 92])
            cv2.imwrite(f"{stem}_mask.png", mask[:, ::-1] if shot.mirrored else mask)
            Path(f"{stem}.box").write_text(" ".join(f"{v:.1f}" for v in shot.box))
            count += 1
    return count


def network(channels: tuple[int, ...] = CHANNELS, outputs: int = 1, inputs: int = 3):
    """The U-Net (module docstring, step 2): (n, ``inputs``, s, s) (normalised RGB) → (n,
    ``outputs``, s, s) logits, one scale per entry of ``channels``."""
    import torch
    from torch import nn
    from torch.nn import functional as F

    def block(i: int, o: int):
        return nn.Sequential(nn.Conv2d(i, o, 3, padding=1, bias=False), nn.BatchNorm2d(o), nn.ReLU(inplace=True),
                             nn.Conv2d(o, o, 3, padding=1, bias=False), nn.BatchNorm2d(o), nn.ReLU(inplace=True))

    class UNet(nn.Module):
        def __init__(self, c=channels):
            super().__init__()
            self.down = nn.ModuleList([block(i, o) for i, o in zip((inputs, *c[:-1]), c)])
            self.context = nn.Sequential(nn.Conv2d(c[-1], c[-1], 3, padding=2, dilation=2), nn.ReLU(inplace=True))
            self.up = nn.ModuleList([block(c[k + 1] + c[k], c[k]) for k in reversed(range(len(c) - 1))])
            self.head = nn.Conv2d(c[0], outputs, 1)

        def forward(self, x):
            skips = []
            for k, stage in enumerate(self.down):
                x = stage(x if k == 0 else F.max_pool2d(x, 2))
                skips.append(x)
            x = self.context(skips.pop())
            for stage in self.up:
                skip = skips.pop()
                x = stage(torch.cat([F.interpolate(x, size=skip.shape[2:], mode="bilinear", align_corners=False),
                                     skip], 1))
            return self.head(x)

    return UNet()


def square_crop(image: np.ndarray, box, margin: float, shift=(0.0, 0.0),
                side: int = INPUT_PX) -> tuple[np.ndarray, np.ndarray]:
    """(the square round ``box`` (x0, y0, x1, y1) px, ``margin`` of its longer side added and its
    centre moved by ``shift`` of the box, scaled to ``side`` px; the (2, 3) affine map photo →
    crop)."""
    import cv2

    x0, y0, x1, y1 = box
    cx, cy = (x0 + x1) / 2 + shift[0] * (x1 - x0), (y0 + y1) / 2 + shift[1] * (y1 - y0)
    s = side / (max(x1 - x0, y1 - y0) * (1 + margin))
    M = np.array([[s, 0, side / 2 - s * cx], [0, s, side / 2 - s * cy]], np.float32)
    flags = cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR
    return cv2.warpAffine(image, M, (side, side), flags=flags, borderMode=cv2.BORDER_REPLICATE), M


def as_input(rgb: np.ndarray):
    """(3, s, s) float tensor of an (s, s, 3) uint8 RGB crop, normalised as ImageNet's networks are."""
    import torch

    mean, std = np.array([0.485, 0.456, 0.406], np.float32), np.array([0.229, 0.224, 0.225], np.float32)
    return torch.from_numpy(((rgb.astype(np.float32) / 255 - mean) / std).transpose(2, 0, 1).copy())


def training_pair(image: np.ndarray, mask: np.ndarray, box, rng: np.random.Generator):
    """(input (3, s, s), target (1, s, s) in {0, 1}) of one render, randomly cropped and spoilt."""
    import cv2
    import torch

    crop, M = square_crop(image, box, rng.uniform(0.05, 0.35), rng.uniform(-0.06, 0.06, 2))
    target = cv2.warpAffine(mask, M, (INPUT_PX, INPUT_PX), flags=cv2.INTER_LINEAR) > 127
    if rng.random() < 0.5:
        crop, target = crop[:, ::-1], target[:, ::-1]
    x = crop.astype(np.float32) * rng.uniform(0.7, 1.3) + rng.uniform(-25, 25)  # exposure
    x = x * rng.uniform(0.85, 1.15, 3)                                          # white balance
    if rng.random() < 0.3:
        x = cv2.GaussianBlur(x, (0, 0), rng.uniform(0.3, 1.0))
    x = np.clip(x + rng.normal(0, rng.uniform(0, 6), x.shape), 0, 255).astype(np.uint8)
    return as_input(x), torch.from_numpy(target.astype(np.float32).copy())[None]


def train(renders: Path, out: Path, epochs: int, seed: int = 0) -> list[float]:
    """Train the U-Net on ``renders`` (module docstring, step 2), save it to ``out``: the mean loss
    of each epoch (binary cross-entropy, wheels weighted 3, plus the soft Dice loss)."""
    import cv2
    import torch
    from torch.nn import functional as F

    torch.manual_seed(seed)
    data = [(cv2.imread(str(f))[..., ::-1].copy(), cv2.imread(str(f).replace(".jpg", "_mask.png"), 0),
             [float(v) for v in f.with_suffix(".box").read_text().split()]) for f in sorted(renders.glob("*.jpg"))]

    def batch_loss(net, items, rng):
        xs, ys = zip(*[training_pair(*item, rng) for item in items])
        x, y = torch.stack(xs), torch.stack(ys)
        logits = net(x)
        p = torch.sigmoid(logits)
        dice = 1 - (2 * (p * y).sum((1, 2, 3)) + 1) / (p.sum((1, 2, 3)) + y.sum((1, 2, 3)) + 1)
        return F.binary_cross_entropy_with_logits(logits, y, pos_weight=torch.tensor(3.0)) + dice.mean()

    return fit_network(network(), data, epochs, seed, batch_loss, out)


def fit_network(net, data: list, epochs: int, seed: int, batch_loss, out: Path, batch: int = 16) -> list[float]:
    """Train ``net`` on ``data`` (one item per render, shuffled from ``seed`` each epoch) in batches
    of ``batch``, ``batch_loss(net, items, rng)`` giving each one's loss (AdamW, a one-cycle
    rate); save its weights to ``out``: the mean loss of each epoch."""
    import torch

    steps = len(data) // batch
    optimiser = torch.optim.AdamW(net.parameters(), 2e-3, weight_decay=1e-4)
    schedule = torch.optim.lr_scheduler.OneCycleLR(optimiser, 3e-3, total_steps=epochs * steps)
    rng, losses = np.random.default_rng(seed), []
    for _ in range(epochs):
        order, total, start = rng.permutation(len(data)), 0.0, time.perf_counter()
        net.train()
        for k in range(steps):
            loss = batch_loss(net, [data[i] for i in order[k * batch:(k + 1) * batch]], rng)
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            schedule.step()
            total += float(loss.detach())
        losses.append(total / steps)
        print(f"epoch {len(losses)}: loss {losses[-1]:.3f} ({time.perf_counter() - start:.0f} s)", flush=True)
    torch.save(net.state_dict(), out)
    return losses


def points_box(points) -> tuple[float, float, float, float]:
    """The box of marks ``points`` [(u, v), ...], taken :data:`BELOW_MARKS` of its height lower,
    photo px."""
    pts = np.asarray(points, float).reshape(-1, 2)
    (x0, y0), (x1, y1) = pts.min(0), pts.max(0)
    return float(x0), float(y0), float(x1), float(y1 + BELOW_MARKS * (y1 - y0))


def marks_box(photo: real.Photo) -> tuple[float, float, float, float]:
    """The photo's marks' box, taken :data:`BELOW_MARKS` of its height lower, photo px."""
    return points_box(list(photo.meta["keypoints"].values()))


def wheels_found(net, rgb: np.ndarray, box, size: float) -> tuple[np.ndarray, np.ndarray]:
    """(the wheel pixels (h, w) bool, the centroids (k, 2) px of the wheels found) in a photo
    (module docstring, step 3)."""
    import cv2
    import torch

    crop, M = square_crop(rgb, box, MARGIN)
    with torch.no_grad():
        p = torch.sigmoid(net(as_input(crop)[None]))[0, 0].numpy()
    h, w = rgb.shape[:2]
    pixels = cv2.warpAffine(p, cv2.invertAffineTransform(M), (w, h), flags=cv2.INTER_LINEAR) > 0.5
    n, _, stats, centroids = cv2.connectedComponentsWithStats(pixels.astype(np.uint8))
    keep = [i for i in range(1, n) if stats[i, cv2.CC_STAT_AREA] > 3 * (0.01 * size) ** 2]
    return pixels, centroids[keep].reshape(-1, 2)


def trained_network(weights: Path):
    """The U-Net with the weights saved at ``weights``, ready to read photos."""
    import torch

    net = network()
    net.load_state_dict(torch.load(weights))
    return net.eval()


def fitted_box(folder: Path) -> tuple[float, float, float, float]:
    """The box of the fitted car's control points (both halves) in the photo, px, of a
    ``bench_real_photos.py --out`` run's ``folder``."""
    from carbody.fit.report import project_with_camera
    from carbody.wireframe import MIRROR

    report, wireframe = real.fitted(folder)
    points = wireframe.control_points
    uv = project_with_camera(report["fit"]["camera"], np.vstack([points, points * MIRROR]))
    return (*map(float, uv.min(0)), *map(float, uv.max(0)))


def measure(net, data: Path, fitted: Path | None = None) -> list[dict]:
    """One row per real photo with annotated wheels (module docstring, step 3); ``found_px``
    holds the centroids of the wheels found. Given ``fitted`` (a ``bench_real_photos.py --out``
    folder), the network reads the fitted car's box (:func:`fitted_box`) where the run made a
    body, not the marks'."""
    import cv2

    rows = []
    for photo in real.load_photos(data):
        annotated = real.annotated_wheel_centres(photo)
        if not len(annotated):
            continue
        rgb = cv2.imread(str(photo.image))[..., ::-1].copy()
        size, _ = real.car_image_size(photo)
        body = None if fitted is None else fitted / photo.name
        box = fitted_box(body) if body is not None and (body / "report.json").is_file() else marks_box(photo)
        pixels, found = wheels_found(net, rgb, box, size)
        human = np.zeros(pixels.shape, np.uint8)
        for q in photo.parts["wheel"]:
            cv2.fillPoly(human, [np.asarray(q).reshape(-1, 2).round().astype(np.int32)], 1)
        iou = float((pixels & (human > 0)).sum() / max(1, (pixels | (human > 0)).sum()))
        pairs = real.wheel_matches(annotated, found) if len(found) else []
        rows.append({"photo": photo.name, "annotated": len(annotated), "found": len(found), "iou": iou,
                     "found_px": found.tolist(), "missed": len(annotated) - len(pairs),
                     "distance_pct": 100.0 * float(np.mean([d for *_, d in pairs])) / size if pairs else None})
    return rows


def onto_wheels_found(seen: np.ndarray, hubs: np.ndarray, found: np.ndarray,
                      near_px: float) -> tuple[np.ndarray, np.ndarray]:
    """((4, 2) the tyres seen, (4, 2) their hubs), px: each tyre seen moved onto the nearest wheel
    ``found`` (k, 2) within ``near_px`` of it, and its hub by the same shift; the others as they
    are."""
    tyres, centres = np.array(seen, float), np.array(hubs, float)
    for k in range(len(tyres)):
        d = np.linalg.norm(found - seen[k], axis=1) if len(found) else np.array([np.inf])
        if d.min() < near_px:
            tyres[k] = found[d.argmin()]
            centres[k] += tyres[k] - seen[k]  # the hub goes with its tyre
    return tyres, centres


def with_the_fit(found_px: dict[str, list], data: Path, fitted: Path, near_pct: list[float]) -> list[dict]:
    """One row per real photo with annotated wheels and a body in ``fitted`` (module docstring,
    step 4), given the wheels found in each ({photo: [[u, v], ...]}, :func:`measure`):
    ``fitted_pct``, the like-for-like distance of the fitted tyres, and ``moved_pct`` {near: the
    same with the tyres moved onto the wheels found within ``near`` % of S}; ``hubs_pct`` and
    ``moved_hubs_pct``, the same by hub (the headline measure), each hub moved with its tyre
    (:func:`onto_wheels_found`)."""
    rows = []
    for photo in real.load_photos(data):
        annotated, folder = real.annotated_wheel_centres(photo), fitted / photo.name
        if not len(annotated) or not (folder / "body.step").is_file():
            continue
        report, wireframe = real.fitted(folder)
        hubs, seen = real.tyres_seen(photo, report["fit"]["camera"], wireframe.control_points, folder)
        size, _ = real.car_image_size(photo)
        found = np.asarray(found_px.get(photo.name, []), float).reshape(-1, 2)

        def distance(tyres: np.ndarray) -> float:
            return 100.0 * float(np.mean([d for *_, d in real.wheel_matches(annotated, tyres)])) / size

        moved, moved_hubs = {}, {}
        for near in near_pct:
            tyres, centres = onto_wheels_found(seen, hubs, found, near * size / 100.0)
            moved[near], moved_hubs[near] = distance(tyres), distance(centres)
        rows.append({"photo": photo.name, "fitted_pct": distance(seen), "moved_pct": moved,
                     "hubs_pct": distance(hubs), "moved_hubs_pct": moved_hubs})
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workdir", type=Path, required=True, help="renders and weights go here (reused)")
    parser.add_argument("--data", type=Path, default=real.DATA, help="the real photos")
    parser.add_argument("--images-per-body", type=int, default=20)
    parser.add_argument("--epochs", type=int, default=14)
    parser.add_argument("--threads", type=int, default=2, help="torch's threads for training")
    parser.add_argument("--seed", type=int, default=0, help="the training's seed (the renders' is fixed)")
    parser.add_argument("--plain-wheels", action="store_true",
                        help="the data set's plain wheels (a flat grey disc), not varied rims")
    parser.add_argument("--fitted", type=Path, help="a bench_real_photos.py --out folder: the fit's tyres with them")
    parser.add_argument("--box", choices=("marks", "fitted"), default="marks",
                        help="the box the network reads: the marks' (taken lower) or the --fitted car's")
    parser.add_argument("--near", type=float, nargs="+", default=[3.0, 5.0],
                        help="move a fitted tyre onto a wheel found within this %% of S (each value)")
    parser.add_argument("--json", type=Path, help="also write the rows and summary here")
    args = parser.parse_args(argv)
    if args.box == "fitted" and args.fitted is None:
        parser.error("--box fitted needs --fitted DIR")
    import torch

    torch.set_num_threads(args.threads)
    renders, weights = args.workdir / "renders", args.workdir / "tyres.pt"
    start = time.perf_counter()
    if not renders.is_dir():
        count = render(renders, args.images_per_body, plain_wheels=args.plain_wheels)
        print(f"rendered {count} pictures in {time.perf_counter() - start:.0f} s")
    if not weights.is_file():
        start = time.perf_counter()
        train(renders, weights, args.epochs, args.seed)
        print(f"trained in {time.perf_counter() - start:.0f} s")
    if not (args.data / "parts.json").is_file():
        print(f"no real photos at {args.data}: nothing to measure")
        return 0
    net = trained_network(weights)
    rows = measure(net, args.data, args.fitted if args.box == "fitted" else None)
    print("\n| photo | wheels annotated / found | missed | IoU | centroid distance, % of S |\n|---|---|---|---|---|")
    for r in rows:
        d = "–" if r["distance_pct"] is None else f"{r['distance_pct']:.1f}"
        print(f"| {r['photo']} | {r['annotated']} / {r['found']} | {r['missed']} | {r['iou']:.2f} | {d} |")
    distances = [r["distance_pct"] for r in rows if r["distance_pct"] is not None]
    summary = {"photos": len(rows), "median_iou": statistics.median(r["iou"] for r in rows),
               "median_distance_pct": statistics.median(distances) if distances else None,
               "missed": sum(r["missed"] for r in rows), "annotated": sum(r["annotated"] for r in rows)}
    print(f"\nmedian IoU {summary['median_iou']:.2f}; median centroid distance "
          f"{summary['median_distance_pct']:.1f} % of S (of {len(distances)} photos); "
          f"wheels missed {summary['missed']} of {summary['annotated']}")
    if args.fitted:
        fit_rows = with_the_fit({r["photo"]: r["found_px"] for r in rows}, args.data, args.fitted, args.near)
        print("\n| photo | like for like: fitted | " + " | ".join(f"moved within {n:g} % of S" for n in args.near)
              + " | by hub: fitted | " + " | ".join(f"moved within {n:g} %" for n in args.near)
              + " |\n|---|---|" + "---|" * (2 * len(args.near) + 1))
        for r in fit_rows:
            print(f"| {r['photo']} | {r['fitted_pct']:.1f} | "
                  + " | ".join(f"{r['moved_pct'][n]:.1f}" for n in args.near) + f" | {r['hubs_pct']:.1f} | "
                  + " | ".join(f"{r['moved_hubs_pct'][n]:.1f}" for n in args.near) + " |")
        median = lambda key: statistics.median(r[key] for r in fit_rows)  # noqa: E731
        summary["fitted_median_pct"], summary["hubs_median_pct"] = median("fitted_pct"), median("hubs_pct")
        summary["moved_median_pct"] = {n: statistics.median(r["moved_pct"][n] for r in fit_rows) for n in args.near}
        summary["moved_hubs_median_pct"] = {n: statistics.median(r["moved_hubs_pct"][n] for r in fit_rows)
                                            for n in args.near}
        print(f"\nmedians of {len(fit_rows)} photos, like for like: fitted {summary['fitted_median_pct']:.2f} %; "
              + "; ".join(f"moved within {n:g} %: {v:.2f} %" for n, v in summary["moved_median_pct"].items())
              + f". By hub: fitted {summary['hubs_median_pct']:.2f} %; "
              + "; ".join(f"moved within {n:g} %: {v:.2f} %" for n, v in summary["moved_hubs_median_pct"].items()))
        rows = {"alone": rows, "with_the_fit": fit_rows}
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "summary": summary}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
