"""Photo-like renders: what a street photo of a car has that a plain render lacks.

Each switch of :class:`PhotoLook` is one row of the ablation table (docs/view_classifier.md):

- ``camera``: a perspective camera held at a person's height (0.4–2.0 m above the ground) 3–15 m
  from the car, so elevation and perspective follow from where a photographer stands (with
  ``framing``, measured from the car's near side, not its centre: see :func:`person_camera`);
- ``ground``: the ground plane (asphalt, concrete, tiles, with paint lines) seen through the same
  camera, up to a wall or the horizon, and the car's soft contact shadow on it;
- ``environment``: paint and glass shaded by an outdoor light (:class:`carbody.render.Environment`):
  sky and ground mirrored in the clear coat and in the glass, dark cabin behind the glass;
- ``backdrop``: a photo-like backdrop above the ground (walls, buildings, trees, parked cars,
  sky: blurred blocks of muted colours) instead of stripes and colour noise;
- ``artefacts``: lens blur, sensor noise, white balance, vignetting and JPEG compression;
- ``plates``: number plates front and rear (else painted over);
- ``framing``: the car framed as a photo's car box is cropped (:func:`photo_frame_crop`): drawn
  smaller and centred, its box stored, so training crops it as ``carbody view --box`` crops a
  photo, the photo's own edges included (what lies past them repeats their border);
- ``details``: what tells a car's front from its rear on a photo, at the body's own scale
  (:func:`carbody.view.dataset.photo_detail_meshes`): lamps and grilles of varied size sitting
  on the surface, a lower air intake, door mirrors, black trims;
- ``sharp``: artefacts at a photo's scale (a large photo reduced to the crop is sharp and its
  JPEG blocks vanish) and sharp, busy backdrops, instead of blur and JPEG at the render's 128 px;
- ``plate_colours``: plates as the world paints them (white, yellow, red dealer plates, black),
  not white only, so a red patch on the car's end does not by itself say "rear";
- ``tone``: the car's colours shaded as light (:func:`linear_look`) and encoded for display with
  an exposure (:func:`display_encode`), as a camera does; without it the renderer's linear light
  is shown as display values, so a white car's shaded flank comes out dark grey.

``framing``, ``details``, ``sharp``, ``tone`` and ``plate_colours`` came with the second pass of
issue 26; :data:`EARLIER_PHOTO_LOOK` is the first pass.

Everything is numpy on the rendered picture and the scene's camera rays (no extra VTK actors),
so a shot costs one render.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Paint colours as they are common on the road (white, black, silver and grey most of all).
COMMON_PAINT = np.array([
    (0.92, 0.92, 0.91), (0.96, 0.96, 0.95), (0.05, 0.05, 0.06), (0.12, 0.12, 0.13), (0.72, 0.73, 0.75),
    (0.55, 0.56, 0.58), (0.35, 0.36, 0.38), (0.62, 0.06, 0.07), (0.10, 0.20, 0.50), (0.08, 0.10, 0.22),
    (0.82, 0.76, 0.62), (0.40, 0.28, 0.18), (0.90, 0.45, 0.05), (0.85, 0.72, 0.10), (0.15, 0.32, 0.20),
])
COMMON_PAINT_P = np.array([0.14, 0.12, 0.1, 0.06, 0.14, 0.09, 0.07, 0.07, 0.05, 0.03, 0.04, 0.02, 0.02, 0.02, 0.03])


@dataclass(frozen=True)
class PhotoLook:
    """Which photo-like changes a data set's renders get.

    On by default: what the photo ablation (docs/view_classifier.md) found helping or what the
    first pass shipped. ``tone`` is off: with it, two training seeds each did no better on the
    held-out cars' renders (classic front/rear confusions 0.12 against 0.08) nor on the real
    photos. ``plate_colours`` is off: never measured.
    """

    camera: bool = True
    ground: bool = True
    environment: bool = True
    backdrop: bool = True
    artefacts: bool = True
    plates: bool = True
    framing: bool = True
    details: bool = True
    sharp: bool = True
    tone: bool = False
    plate_colours: bool = False


#: The earlier photo-like renders (before framing, details, sharp and tone): the ablation's baseline.
EARLIER_PHOTO_LOOK = PhotoLook(framing=False, details=False, sharp=False, tone=False, plate_colours=False)

#: Display gamma of :func:`display_encode` (sRGB is close to a 2.2 power).
DISPLAY_GAMMA = 2.2


def person_camera(rng: np.random.Generator, lo: np.ndarray, hi: np.ndarray, ground_z: float,
                  radius: float, theta_deg: float | None = None) -> tuple[float, float]:
    """(elevation φ deg, distance from the box centre, model units) of a camera held 0.4–2.0 m
    above the ground (15 %: 2–3.5 m) by a person standing 3–15 m (log-uniform) from a car whose
    box is lo..hi (mm).

    With ``theta_deg`` the 3–15 m are from the near side of the car's box as seen from that
    azimuth, less 1 m (a person stands 2–14 m clear of the bumper or the door, and no nearer
    than 1 m), not from its centre: from the centre, a front view at 3 m puts the camera half a
    metre off the bumper, a distortion no photo shows. None: from the centre (the earlier renders).
    """
    centre_z = (lo[2] + hi[2]) / 2
    height = rng.uniform(400.0, 2000.0) if rng.random() < 0.85 else rng.uniform(2000.0, 3500.0)
    horizontal = float(np.exp(rng.uniform(np.log(3000.0), np.log(15000.0))))
    if theta_deg is not None:
        t = np.radians(theta_deg)
        half = (hi - lo) / 2
        horizontal = max(horizontal - 1000.0, 1000.0) + abs(np.cos(t)) * half[1] + abs(np.sin(t)) * half[0]
    dz = ground_z + height - centre_z
    dist = max(float(np.hypot(horizontal, dz)), 1.15 * radius)
    elevation = float(np.degrees(np.arcsin(np.clip(dz / dist, -0.9, 0.9))))
    return elevation, dist


def _smooth_noise(rng: np.random.Generator, shape: tuple[int, int], cells: int) -> np.ndarray:
    import cv2

    small = rng.normal(0, 1, (max(2, cells), max(2, cells))).astype(np.float32)
    return cv2.resize(small, (shape[1], shape[0]), interpolation=cv2.INTER_CUBIC)


def backdrop(rng: np.random.Generator, size: int, sharp: bool = False) -> np.ndarray:
    """(size, size, 3) float [0, 1]: a street, showroom or parking backdrop; blurred blocks of
    muted colours, or with ``sharp`` the blocks at many scales, some of them windows in rows
    and posts, and little blur (a photo's background is mostly in focus)."""
    import cv2

    h = w = size
    kind = rng.choice(["street", "showroom", "trees", "wall"], p=[0.4, 0.25, 0.2, 0.15])
    sky = np.array([0.62, 0.74, 0.9]) * rng.uniform(0.8, 1.15) if rng.random() < 0.7 else np.full(3, rng.uniform(0.75, 0.97))
    t = np.linspace(0, 1, h)[:, None, None]
    img = np.broadcast_to(sky * (1 - 0.25 * t) + 0.25 * t * np.full(3, 0.9), (h, w, 3)).copy()
    muted = lambda: np.clip(rng.uniform(0.15, 0.9) * (0.7 + 0.3 * rng.uniform(0, 1, 3)), 0, 1)  # noqa: E731
    if kind == "trees":
        green = np.array([0.18, 0.3, 0.14]) * rng.uniform(0.6, 1.4)
        top = int(h * rng.uniform(0.05, 0.5))
        line = (top + 0.12 * h * _smooth_noise(rng, (1, w), 8)[0]).astype(int)
        for x in range(w):
            img[max(0, line[x]):, x] = green
        img += 0.08 * _smooth_noise(rng, (h, w), 24)[..., None]
    elif kind in ("street", "showroom", "wall"):
        wall = muted() if kind != "showroom" else np.full(3, rng.uniform(0.7, 0.95)) * (0.85 + 0.15 * rng.uniform(0, 1, 3))
        top = int(h * rng.uniform(0.0, 0.6)) if kind != "showroom" else 0
        img[top:] = wall
        for _ in range(rng.integers(2, 10) if not sharp else rng.integers(6, 24)):
            # windows, doors, signs, posts, other cars
            bw, bh = int(rng.integers(w // 20, w // 3)), int(rng.integers(h // 20, h // 2))
            if sharp and rng.random() < 0.3:
                bw, bh = max(1, bw // 4), max(2, bh // 3)
            x0, y0 = int(rng.integers(-bw // 2, w)), int(rng.integers(0, h))
            img[max(0, y0):y0 + bh, max(0, x0):x0 + bw] = muted()
        if sharp:
            for _ in range(rng.integers(0, 3)):          # a row of windows or a fence
                y0, n = int(rng.integers(top, h)), int(rng.integers(3, 10))
                pitch, bw, bh = int(rng.integers(4, 14)), int(rng.integers(2, 8)), int(rng.integers(2, 10))
                colour, x = muted(), int(rng.integers(-pitch, w // 2))
                for i in range(n):
                    img[y0:y0 + bh, max(0, x + i * pitch):max(0, x + i * pitch + min(bw, pitch - 1))] = colour
            for _ in range(rng.integers(0, 4)):          # posts, poles, pillars
                x0, pw = int(rng.integers(0, w)), int(rng.integers(1, 4))
                img[int(rng.integers(0, h // 2)):, x0:x0 + pw] = muted()
        if kind == "showroom" and rng.random() < 0.6:   # a strip of ceiling lights
            y = int(rng.integers(0, h // 4))
            img[y:y + max(1, h // 40)] = 1.0
    img += rng.uniform(0.0, 0.06) * rng.normal(0, 1, img.shape)
    sigma = rng.uniform(0.5, 2.5) if not sharp else rng.uniform(0.0, 1.0)
    if sigma > 0.2:
        img = cv2.GaussianBlur(img.astype(np.float32), (0, 0), sigma)
    return np.clip(img, 0, 1).astype(np.float32)


def ground_and_shadow(scene, rng: np.random.Generator, ground_z: float, lo: np.ndarray, hi: np.ndarray,
                      back: np.ndarray, with_ground: bool) -> np.ndarray:
    """(h, w, 3) float background of the last (perspective) render: the ground plane z = ground_z
    up to a wall 8–60 m away or the horizon, the car's soft contact shadow on it, ``back`` above."""
    pos, rays = scene.pixel_rays()
    if not with_ground:
        return back
    rz = rays[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (ground_z - pos[2]) / rz
    hit = (rz < 0) & np.isfinite(t) & (t > 0)
    gx = pos[0] + np.where(hit, t, 0) * rays[..., 0]
    gy = pos[1] + np.where(hit, t, 0) * rays[..., 1]
    centre = (lo[:2] + hi[:2]) / 2
    depth = np.hypot(gx - centre[0], gy - centre[1])
    wall = float(np.exp(rng.uniform(np.log(8000.0), np.log(60000.0))))
    hit &= depth < wall
    kind = rng.choice(["asphalt", "concrete", "tiles"], p=[0.5, 0.3, 0.2])
    base = {"asphalt": rng.uniform(0.18, 0.42), "concrete": rng.uniform(0.45, 0.7),
            "tiles": rng.uniform(0.5, 0.85)}[kind]
    colour = base * (0.92 + 0.08 * rng.uniform(0, 1, 3))
    tex = np.sin(gx / rng.uniform(200, 900) + 3 * np.sin(gy / 1700.0)) * 0.02
    if kind == "tiles":
        step = rng.uniform(400, 1200)
        tex += -0.08 * ((np.abs((gx / step) % 1 - 0.5) > 0.47) | (np.abs((gy / step) % 1 - 0.5) > 0.47))
    grain = rng.normal(0, rng.uniform(0.01, 0.05), rz.shape)
    ground = colour[None, None, :] * (1 + tex + grain)[..., None]
    if rng.random() < 0.5:                     # parking / lane lines
        across = rng.random() < 0.5
        coord = gx if across else gy
        step = rng.uniform(2400, 5500)
        line = np.abs(((coord + rng.uniform(0, step)) / step) % 1 - 0.5) * step > step / 2 - 60
        ground = np.where(line[..., None], np.array([0.85, 0.85, 0.8]) if rng.random() < 0.7 else
                          np.array([0.85, 0.7, 0.15]), ground)
    # contact shadow: dark under the car, soft edges, a little longer on the sun's side
    half = (hi[:2] - lo[:2]) / 2 * np.array([0.95, 0.97])
    dx = np.maximum(np.abs(gx - centre[0]) - half[0], 0)
    dy = np.maximum(np.abs(gy - centre[1]) - half[1], 0)
    out_d = np.hypot(dx, dy)
    inside = np.minimum(half[0] - np.abs(gx - centre[0]), half[1] - np.abs(gy - centre[1]))
    soft = rng.uniform(150, 600)
    shade = np.where(inside > 0, 0.15 + 0.25 * np.exp(-np.maximum(inside, 0) / 300.0),
                     1 - 0.6 * np.exp(-out_d / soft))
    shade = 1 - (1 - shade) * rng.uniform(0.6, 1.0)
    ground = ground * shade[..., None]
    return np.where(hit[..., None], ground, back)


def artefacts(img: np.ndarray, rng: np.random.Generator, sharp: bool = False) -> np.ndarray:
    """Lens blur, white balance, vignetting, sensor noise and JPEG compression: uint8 in and out.

    With ``sharp`` the blur and the JPEG blocks are those of a large photo after its reduction to
    the crop: a phone photo's car is 500–2000 px wide and the crop shrinks it 5–20 times, so its
    blur is a fraction of a crop pixel and its JPEG blocks average away; without, they are applied
    at the render's own 128 px (blurrier and blockier than any photo's crop)."""
    import cv2

    x = img.astype(np.float32) / 255.0
    if rng.random() < (0.5 if not sharp else 0.25):
        x = cv2.GaussianBlur(x, (0, 0), rng.uniform(0.3, 1.0) if not sharp else rng.uniform(0.2, 0.5))
    x = x * (1 + rng.normal(0, 0.04, 3)).astype(np.float32)             # white balance
    x = np.clip(x, 0, 1) ** rng.uniform(0.85, 1.15)                      # exposure curve
    if rng.random() < 0.4:
        h, w = x.shape[:2]
        yy, xx = np.mgrid[0:h, 0:w]
        r2 = ((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / (0.5 * (h * h + w * w))
        x = x * (1 - rng.uniform(0.1, 0.35) * r2)[..., None]
    x = x + rng.normal(0, rng.uniform(0, 0.025 if not sharp else 0.012), x.shape)
    out = np.clip(x * 255 + 0.5, 0, 255).astype(np.uint8)
    if rng.random() < (0.8 if not sharp else 0.4):
        quality = int(rng.integers(35, 95)) if not sharp else int(rng.integers(70, 96))
        ok, buf = cv2.imencode(".jpg", out[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, quality])
        if ok:
            out = cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1].copy()
    return out


def photo_looks(rng: np.random.Generator, photo: PhotoLook):
    """(paint RGB, glass RGB, detail colours, Environment or None) of one photo-like shot."""
    from carbody.render import Environment

    paint = np.clip(COMMON_PAINT[rng.choice(len(COMMON_PAINT), p=COMMON_PAINT_P / COMMON_PAINT_P.sum())]
                    + rng.normal(0, 0.03, 3), 0, 1)
    glass = np.clip(np.array([0.05, 0.06, 0.07]) * rng.uniform(0.6, 2.0), 0, 1)
    plate = tuple(np.clip(np.array([0.92, 0.92, 0.9]) * rng.uniform(0.75, 1.0) + rng.normal(0, 0.02, 3), 0, 1))
    colours = {"tyre": tuple(np.full(3, rng.uniform(0.03, 0.09))),
               "rim": tuple(np.full(3, rng.uniform(0.25, 0.8))), "underbody": (0.02, 0.02, 0.02),
               "headlight": tuple(np.clip(rng.uniform(0.55, 0.95) + rng.normal(0, 0.03, 3), 0, 1)),
               "grille": tuple(np.full(3, rng.uniform(0.02, 0.2))),
               "taillight": (rng.uniform(0.45, 0.85), rng.uniform(0.0, 0.08), rng.uniform(0.0, 0.08)),
               "plate": plate if photo.plates else tuple(paint)}
    if photo.plates and photo.plate_colours:
        kind = rng.choice(4, p=[0.6, 0.15, 0.15, 0.1])
        base = [np.array([0.92, 0.92, 0.9]), np.array([0.95, 0.8, 0.15]), np.array([0.8, 0.12, 0.12]),
                np.array([0.08, 0.08, 0.09])][kind]
        colours["plate"] = tuple(np.clip(base * rng.uniform(0.75, 1.0) + rng.normal(0, 0.02, 3), 0, 1))
    if photo.details:
        black = tuple(np.full(3, rng.uniform(0.02, 0.1)))
        if rng.random() < 0.4:                         # black mirror caps (else painted)
            colours["mirror"] = black
        if rng.random() < 0.35:                        # black window surround and pillars
            colours["window_surround"] = black
        if rng.random() < 0.25:                        # black plastic sills (SUVs, pickups)
            colours["sill"] = tuple(np.full(3, rng.uniform(0.04, 0.15)))
        if rng.random() < 0.3:                         # smoked or dark-bezel lamps
            colours["headlight"] = tuple(np.full(3, rng.uniform(0.25, 0.5)))
    env = None
    if photo.environment:
        overcast = rng.random() < 0.35
        sky = (np.full(3, rng.uniform(0.75, 0.95)) if overcast else
               np.clip(np.array([0.6, 0.72, 0.92]) * rng.uniform(0.85, 1.15), 0, 1))
        env = Environment(sky=tuple(sky), ground=tuple(np.full(3, rng.uniform(0.12, 0.4))),
                          horizon_sharpness=float(rng.uniform(6, 25)),
                          sun_azimuth_deg=float(rng.uniform(0, 360)), sun_elevation_deg=float(rng.uniform(15, 75)),
                          sun=float(rng.uniform(0.15, 0.35) if overcast else rng.uniform(0.45, 0.9)),
                          sky_light=float(rng.uniform(0.65, 0.9) if overcast else rng.uniform(0.45, 0.7)),
                          paint_reflectance=float(rng.uniform(0.06, 0.2)),
                          glass_reflectance=float(rng.uniform(0.15, 0.45)),
                          interior=tuple(np.full(3, rng.uniform(0.02, 0.08))))
    return paint, glass, colours, env


def photo_frame_crop(image: np.ndarray, box, rng: np.random.Generator, size: int) -> np.ndarray:
    """(size, size, 3) uint8 network input of a framed render, cropped as a photo of the car would
    be by ``carbody view --box``: the photo's frame is drawn around the car's ``box`` (x0, y0, x1, y1)
    pixels of ``image`` — an aspect of 4:3, 3:2, 16:9, 1:1 or 3:4, the car filling 55–100 % of it,
    anywhere in it — and :func:`carbody.view.predict.crop_to_box` crops that frame, so past the
    frame's edges the crop repeats their border as it does past a photo's. The box is a person's
    box: each side off by ~2.5 % of the car's size, and 30 % of the time grown by up to 15 % of its
    larger side (the box of the marks, grown by 12 %)."""
    from carbody.view.predict import crop_to_box
    from carbody.view.train import to_square_input

    h, w = image.shape[:2]
    b = np.asarray(box, dtype=float)
    bw, bh = b[2] - b[0], b[3] - b[1]
    given = b + rng.normal(0, 0.025, 4) * np.array([bw, bh, bw, bh])
    if rng.random() < 0.3:
        grow = rng.uniform(0, 0.15) * max(bw, bh)
        given += np.array([-grow, -grow, grow, grow])
    aspect = float(rng.choice([4 / 3, 3 / 2, 16 / 9, 1.0, 3 / 4], p=[0.4, 0.25, 0.15, 0.1, 0.1]))
    fw = max(bw, bh * aspect) / rng.uniform(0.55, 1.0)
    fh = fw / aspect
    fx0, fy0 = b[0] - rng.uniform(0, 1) * (fw - bw), b[1] - rng.uniform(0, 1) * (fh - bh)
    x0, y0 = max(0, int(np.floor(fx0))), max(0, int(np.floor(fy0)))
    x1, y1 = min(w, int(np.ceil(fx0 + fw))), min(h, int(np.ceil(fy0 + fh)))
    frame = image[y0:y1, x0:x1]
    given = given - np.array([x0, y0, x0, y0])
    if given[2] - given[0] < 2 or given[3] - given[1] < 2:
        given = b - np.array([x0, y0, x0, y0])
    return to_square_input(crop_to_box(frame, given), size)


def linear_look(look):
    """``look`` with every colour it paints or reflects (paint, glass, detail colours, the
    environment's sky, ground and cabin) turned from display values into light (a 2.2 power), for
    a render that :func:`display_encode` encodes back."""
    from dataclasses import replace

    lin = lambda c: tuple(float(v) ** DISPLAY_GAMMA for v in c)  # noqa: E731
    env = look.environment
    if env is not None:
        env = replace(env, sky=lin(env.sky), ground=lin(env.ground), interior=lin(env.interior))
    return replace(look, paint=lin(look.paint), glass=lin(look.glass),
                   colours={k: lin(v) for k, v in look.colours.items()}, environment=env)


def display_encode(premultiplied: np.ndarray, alpha: np.ndarray, exposure: float) -> np.ndarray:
    """(h, w, 3) uint8 premultiplied render of light values (:func:`linear_look`) as a camera
    encodes it: times ``exposure``, clipped, raised to 1 / :data:`DISPLAY_GAMMA`, premultiplied
    again by the coverage ``alpha`` (h, w)."""
    a = alpha[..., None].astype(np.float32)
    colour = premultiplied.astype(np.float32) / 255.0 / np.maximum(a, 1e-3)
    shown = np.clip(colour * exposure, 0, 1) ** (1 / DISPLAY_GAMMA) * a
    return np.clip(shown * 255 + 0.5, 0, 255).astype(np.uint8)
