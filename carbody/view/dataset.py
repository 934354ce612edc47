"""The rendered multi-view data set (paper III.A, our USMV3085): library bodies, many looks.

Bodies are library models — each template as it is plus sampled expansions — surfaced by our own
pipeline (:func:`carbody.surface.build_body`), with simple wheels (tyre + rim discs) added at
the wheel centres so a render looks like a car rather than a shell. Each body is tessellated once
and rendered many times (:class:`carbody.render.Scene`), each image with its own random look:

- view: one of the 24 classes (:mod:`carbody.view.labels`); left-side classes (0°–180°) are
  rendered, right-side classes are the mirror image (rendered at 360° − θ and flipped), as the
  paper's 13 classes plus their mirror; θ jitters by ±``angle_jitter_deg`` inside its class;
- elevation φ uniform in 0°–30°, a small roll, orthographic or perspective camera at 1.6–6
  car lengths, the car filling 60–100 % of the frame and shifted off centre (crop);
- paint from a palette of real car colours with jitter, glass tint, key light direction and
  strength, ambient, specular;
- background: plain colour, gradient, a street-like scene of sky, ground and blocks, blurred
  colour noise or stripes; then mild blur and sensor noise.

Written to ``OUT_DIR/images/<θ>/<body>_<n>.png`` (128 × 128 RGB) with ``OUT_DIR/manifest.csv``
(one row per image: file, class, θ, φ, body, template, split, ...) and ``OUT_DIR/dataset.json``.
The split is by car: the templates are split 8:2 and every body of a validation template
(its expansions too) is in validation, so no car seen in training is validated on.
Everything follows from ``seed``: the same seed gives the same files.
"""
from __future__ import annotations

import csv
import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from carbody.errors import ViewError
from carbody.view.labels import CLASS_ANGLES_DEG, N_CLASSES
from carbody.view.photo import PhotoLook

#: Side of the stored images, pixels (the network resizes to 64).
IMAGE_SIZE = 128

#: Default number of images (paper: 3085; a multiple of 24 classes above it).
DEFAULT_COUNT = 3096

#: Fraction of templates whose bodies go to validation (paper's 8:2).
VALIDATION_FRACTION = 0.2

#: Real car colours (RGB 0-1): white, black, silvers, greys, reds, blues, green, yellow, orange, brown, beige.
PAINT_PALETTE = np.array([
    (0.93, 0.93, 0.92), (0.05, 0.05, 0.06), (0.72, 0.73, 0.75), (0.55, 0.56, 0.58), (0.32, 0.33, 0.35),
    (0.70, 0.05, 0.06), (0.45, 0.03, 0.05), (0.08, 0.20, 0.55), (0.05, 0.09, 0.25), (0.30, 0.55, 0.80),
    (0.10, 0.30, 0.15), (0.90, 0.75, 0.10), (0.90, 0.40, 0.05), (0.35, 0.22, 0.12), (0.80, 0.74, 0.60),
])


@dataclass(frozen=True)
class Variation:
    """What varies from image to image (the ablation switches these off one at a time).

    Attributes:
        background: textured backgrounds (else plain white).
        colour: random paint, glass and light (else silver paint, dark glass, one light).
        elevation: elevation 0°–30°, roll, perspective, fill and offset jitter (else φ = 10°,
            orthographic, centred at 85 % fill).
        angle_jitter_deg: θ jitter inside its class, degrees.
        photo: photo-like renders (:class:`carbody.view.photo.PhotoLook`: a person's camera,
            ground and contact shadow, environment-lit paint and glass, backdrops, plates, camera
            artefacts) instead of the classic looks above; None: classic.
        photo_fraction: with ``photo``, the share of images that are photo-like (the others classic).
        classic_details: the classic share of a photo-like data set drawn with the classic renders'
            fixed details (:func:`classic_meshes`), not the photo-like ones (off: the ablation's
            rows, rendered before this existed).
    """

    background: bool = True
    colour: bool = True
    elevation: bool = True
    angle_jitter_deg: float = 3.0
    photo: "PhotoLook | None" = None
    photo_fraction: float = 1.0
    classic_details: bool = True


# ----------------------------------------------------------------------------------------- bodies

@dataclass
class BodySpec:
    """A body to render: library model ``model_index`` at its template's real size."""

    body_id: str
    template: str
    model_index: int
    factors: tuple[float, float, float, float]
    control_points_mm: np.ndarray
    tyre_radius_mm: float


def choose_bodies(library, templates_manifest: list[dict], per_template: int, seed: int) -> list[BodySpec]:
    """Each template as it is plus ``per_template − 1`` random expansions of it (seeded)."""
    rng = np.random.default_rng([seed, 1])
    tyre = {row["name"]: float(row.get("tyre_radius_mm") or 0.0) for row in templates_manifest}
    out = []
    for t, name in enumerate(library.template_names):
        models = np.flatnonzero(library.template_index == t)
        original = [j for j in models if np.allclose(library.factors[j], 1.0)]
        others = [j for j in models if j not in original]
        picks = original[:1] + list(rng.choice(others, size=min(len(others), per_template - 1), replace=False))
        wb = float(library.template_wheelbase_mm[t])
        for n, j in enumerate(picks):
            radius = tyre.get(name) or 0.115 * wb
            out.append(BodySpec(
                body_id=f"{_slug(name)}-{n:02d}", template=name, model_index=int(j),
                factors=tuple(float(f) for f in library.factors[j]),
                control_points_mm=library.points(int(j)) * wb / 1000.0, tyre_radius_mm=radius))
    return out


def blend_bodies(library, templates_manifest: list[dict], among: list[str], count: int, seed: int) -> list[BodySpec]:
    """``count`` bodies of more shapes than the templates: a random mix a·A + (1 − a)·B
    (a uniform in 0.2–0.8) of two library models of two different templates of ``among``, at
    the mixed wheelbase and tyre (seeded). Named ``blend-NN``, template ``"A + B"``."""
    rng = np.random.default_rng([seed, 5])
    tyre = {row["name"]: float(row.get("tyre_radius_mm") or 0.0) for row in templates_manifest}
    index = {n: t for t, n in enumerate(library.template_names)}
    out = []
    for n in range(count if len(among) >= 2 else 0):
        a_name, b_name = rng.choice(sorted(among), size=2, replace=False)
        ja, jb = (int(rng.choice(np.flatnonzero(library.template_index == index[x]))) for x in (a_name, b_name))
        a = rng.uniform(0.2, 0.8)
        wa, wb = (float(library.template_wheelbase_mm[index[x]]) for x in (a_name, b_name))
        wbase = a * wa + (1 - a) * wb
        cp = (a * library.points(ja) + (1 - a) * library.points(jb)) * wbase / 1000.0
        radius = a * (tyre.get(a_name) or 0.115 * wa) + (1 - a) * (tyre.get(b_name) or 0.115 * wb)
        out.append(BodySpec(body_id=f"blend-{n:02d}", template=f"{a_name} + {b_name}", model_index=-1,
                            factors=(float(a), 0.0, 0.0, 0.0), control_points_mm=cp, tyre_radius_mm=radius))
    return out


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name.lower()).strip("_")


def wheel_meshes(control_points_mm: np.ndarray, tyre_radius_mm: float, segments: int = 40):
    """Four simple wheels (tyre tread + sidewall ``"tyre"``, a ``"rim"`` disc) at the wheel centres,
    dark wheel wells and a floor (``"underbody"``) so no background shows through the open shell.

    Returns:
        list of :class:`carbody.render.FaceMesh`, mm, both sides of the car.
    """
    from carbody.render.mesh import FaceMesh, mirrored
    from carbody.topology import load_topology
    from carbody.wireframe import wheel_centre

    topo = load_topology()
    cp = np.asarray(control_points_mm, dtype=float)
    front = wheel_centre(cp, topo, "front")
    rear = wheel_centre(cp, topo, "rear")
    wheelbase = float(np.hypot(*(rear - front)))
    arch_x = []
    for region in ("front_wheel_arch", "rear_wheel_arch"):
        idx = [4 * c + i for c, _ in topo.region(region).loop for i in range(4)]
        arch_x.append(cp[idx, 0].min())
    x_out = float(min(arch_x)) + 0.035 * wheelbase
    width = 0.075 * wheelbase
    R, r_rim = tyre_radius_mm, 0.64 * tyre_radius_mm
    a = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a)], axis=1)            # (s, 2) in (y, z)
    i = np.arange(segments)
    j = (i + 1) % segments
    meshes = []
    for (yc, zc) in (front, rear):
        def at(x, rad):
            return np.c_[np.full(segments, x), yc + rad * ring[:, 0], zc + rad * ring[:, 1]]
        # tread: outer ring at x_out - width .. x_out; sidewall: annulus r_rim..R at x_out
        tread_v = np.vstack([at(x_out - width, R), at(x_out, R)])
        tread_t = np.r_[np.c_[i, j, i + segments], np.c_[j, j + segments, i + segments]]
        side_v = np.vstack([at(x_out, r_rim), at(x_out, R)])
        side_t = np.r_[np.c_[i, i + segments, j], np.c_[j, i + segments, j + segments]]
        rim_v = np.vstack([at(x_out + 1.0, r_rim), [[x_out + 1.0 - 0.02 * R, yc, zc]]])
        rim_t = np.c_[np.full(segments, segments), j, i]
        # wheel well: a dark upper half-disc inboard of the tyre, so the arch does not show the sky
        b = np.radians(np.linspace(-15, 195, segments))
        x_in = x_out - width - 2.0
        well_v = np.vstack([np.c_[np.full(segments, x_in), yc + 1.3 * R * np.cos(b), zc + 1.3 * R * np.sin(b)],
                            [[x_in, yc, zc]]])
        well_t = np.c_[np.full(segments - 1, segments), np.arange(segments - 1), np.arange(1, segments)]
        meshes += [FaceMesh("tyre", tread_v, tread_t), FaceMesh("tyre", side_v, side_t),
                   FaceMesh("rim", rim_v, rim_t), FaceMesh("underbody", well_v, well_t)]
    # underbody: a dark floor at the wheel-centre height between the wheels' inner faces
    y0, y1 = front[0] - 1.3 * R, rear[0] + 1.3 * R
    zf = (front[1] + rear[1]) / 2
    floor_v = np.array([[0.0, y0, zf], [x_out - width - 2.0, y0, zf], [x_out - width - 2.0, y1, zf], [0.0, y1, zf]])
    meshes.append(FaceMesh("underbody", floor_v, np.array([[0, 1, 2], [0, 2, 3]])))
    return meshes + mirrored(meshes)


#: Lamps and grille on the front face / tail, as fractions of the region's half-width (x, from the
#: symmetry plane) and height (z, from the region's top): (name, region, x0, x1, z0, z1, outward y).
DETAILS = (
    ("headlight", "front_face", 0.55, 0.93, 0.06, 0.32, -1.0),
    ("grille", "front_face", 0.0, 0.45, 0.30, 0.62, -1.0),
    ("taillight", "tail", 0.58, 0.95, 0.05, 0.30, 1.0),
    ("plate", "front_face", 0.0, 0.27, 0.66, 0.86, -1.0),
    ("plate", "tail", 0.0, 0.27, 0.45, 0.66, 1.0),
)


def detail_meshes(meshes, grid: int = 6):
    """Head lights, grille and tail lights as thin patches lying on the body's front face and tail
    (both sides), so a render shows which end is the front as a photo does.

    Each patch is a (grid × grid) sheet over the left half's region vertices, 3 mm proud of the
    surface; names ``headlight``, ``grille``, ``taillight`` (colours come from the Look).
    """
    from carbody.render.mesh import FaceMesh, mirrored

    out = []
    for name, region, x0, x1, z0, z1, out_y in DETAILS:
        v = np.concatenate([m.vertices for m in meshes if m.name == region] or [np.zeros((0, 3))])
        v = v[v[:, 0] >= 0]
        if len(v) < 10:
            continue
        xmax, ztop, zbot = v[:, 0].max(), v[:, 2].max(), v[:, 2].min()
        h = ztop - zbot
        gx, gz = np.meshgrid(np.linspace(x0, x1, grid) * xmax, ztop - np.linspace(z0, z1, grid) * h)
        q = np.c_[gx.ravel(), gz.ravel()]
        d = np.linalg.norm(v[None, :, [0, 2]] - q[:, None, :], axis=2)        # (g², n)
        near = d <= max(d.min(axis=1).max(), 0.03 * h) * 1.5
        y = np.where(near, v[None, :, 1] * out_y, -np.inf).max(axis=1) * out_y + 3.0 * out_y
        verts = np.c_[q[:, 0], y, q[:, 1]]
        i, k = np.meshgrid(np.arange(grid - 1), np.arange(grid - 1), indexing="ij")
        a = (i * grid + k).ravel()
        tris = np.r_[np.c_[a, a + 1, a + grid], np.c_[a + 1, a + grid + 1, a + grid]]
        out.append(FaceMesh(name, verts, tris))
    return out + mirrored(out)


#: Ranges of the photo-like details (:func:`photo_detail_meshes`), as fractions of the region's
#: half-width (x, from the symmetry plane) and height (z, from the region's top), drawn per body:
#: (name, region, (x0 range), (x1 range), (z0 range), (height range), outward y, probability).
PHOTO_DETAILS = (
    ("headlight", "front_face", (0.42, 0.68), (0.86, 0.97), (0.0, 0.12), (0.14, 0.36), -1.0, 1.0),
    ("grille", "front_face", (0.0, 0.0), (0.28, 0.62), (0.06, 0.34), (0.14, 0.42), -1.0, 1.0),
    ("grille", "front_face", (0.0, 0.0), (0.3, 0.85), (0.58, 0.76), (0.07, 0.2), -1.0, 0.7),   # lower intake
    ("plate", "front_face", (0.0, 0.0), (0.22, 0.3), (0.45, 0.7), (0.14, 0.22), -1.0, 1.0),
    ("taillight", "tail", (0.45, 0.72), (0.88, 0.98), (0.0, 0.14), (0.12, 0.32), 1.0, 1.0),
    ("plate", "tail", (0.0, 0.0), (0.22, 0.3), (0.3, 0.6), (0.16, 0.24), 1.0, 1.0),
    ("grille", "tail", (0.0, 0.0), (0.5, 0.9), (0.82, 0.9), (0.08, 0.14), 1.0, 0.35),           # black diffuser
)


def _surface_patch(name: str, region: list, x0: float, x1: float, z0: float, z1: float, out_y: float,
                   grid: int = 10, lift: float = 4.0):
    """A (grid × grid) sheet lying on a region of the left half, ``lift`` mm off the surface along
    its normal: each grid point (x, z) is cast along y onto the region's triangles and takes the
    outermost hit (toward ``out_y``), so the sheet follows the surface round its corners instead
    of floating behind a curved tail. Grid cells with a corner off the region are left out.
    None when nothing lands on the region."""
    from carbody.render.mesh import FaceMesh

    v = np.concatenate([m.vertices for m in region])
    t = np.concatenate([m.triangles + o for m, o in zip(region, np.cumsum([0] + [len(m.vertices) for m in region])[:-1])])
    t = t[v[t].mean(axis=1)[:, 0] >= 0]
    if len(t) == 0:
        return None
    used = v[np.unique(t)]
    xmax, ztop, zbot = used[:, 0].max(), used[:, 2].max(), used[:, 2].min()
    gx, gz = np.meshgrid(np.linspace(x0, x1, grid) * xmax, ztop - np.linspace(z0, z1, grid) * (ztop - zbot))
    q = np.c_[gx.ravel(), gz.ravel()]                                  # (g², 2) in (x, z)
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    e0, e1 = (b - a)[:, [0, 2]], (c - a)[:, [0, 2]]
    den = e0[:, 0] * e1[:, 1] - e1[:, 0] * e0[:, 1]
    ok = np.abs(den) > 1e-9
    d = q[:, None, :] - a[None, :, [0, 2]]                              # (g², m, 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (d[..., 0] * e1[:, 1] - e1[:, 0] * d[..., 1]) / den
        w = (e0[:, 0] * d[..., 1] - d[..., 0] * e0[:, 1]) / den
        inside = ok & (u >= -1e-6) & (w >= -1e-6) & (u + w <= 1 + 1e-6)
        y = np.where(inside, a[:, 1] + u * (b - a)[:, 1] + w * (c - a)[:, 1], 0.0)
    score = np.where(inside, y * out_y, -np.inf)
    best = score.argmax(axis=1)
    hit = np.isfinite(score.max(axis=1))
    if hit.sum() < 4:
        return None
    normal = np.cross(b - a, c - a)[best]
    normal /= np.linalg.norm(normal, axis=1, keepdims=True) + 1e-12
    normal *= np.where(normal[:, 1] * out_y < 0, -1.0, 1.0)[:, None]
    verts = np.c_[q[:, 0], y[np.arange(len(q)), best], q[:, 1]] + lift * normal
    i, k = np.meshgrid(np.arange(grid - 1), np.arange(grid - 1), indexing="ij")
    first = (i * grid + k).ravel()
    quads = np.c_[first, first + 1, first + grid, first + grid + 1]
    quads = quads[hit[quads].all(axis=1)]
    if len(quads) == 0:
        return None
    tris = np.r_[quads[:, [0, 1, 2]], quads[:, [1, 3, 2]]]
    if out_y < 0:                                       # counter-clockwise seen from outside
        tris = tris[:, ::-1]
    used, tris = np.unique(tris, return_inverse=True)   # only the grid points the cells use
    return FaceMesh(name, verts[used], tris.reshape(-1, 3))


def _box_mesh(name: str, lo: np.ndarray, hi: np.ndarray):
    """An axis-aligned box lo..hi (mm) as a closed mesh, normals outward."""
    from carbody.render.mesh import FaceMesh

    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    return FaceMesh(name, corners, tris)


def photo_detail_meshes(meshes, control_points_mm: np.ndarray, rng: np.random.Generator):
    """What tells a car's front from its rear on a photo, drawn per body from :data:`PHOTO_DETAILS`
    (``rng`` chooses sizes and places): head lamps, grille and a lower air intake, plates, tail
    lamps and a diffuser as sheets on the front face and tail (:func:`_surface_patch`), and door
    mirrors (``"mirror"``, painted unless the look says black) at the front lower corner of the
    side glass, standing 150–220 mm out of the body. Both sides; mm."""
    from carbody.render.mesh import mirrored
    from carbody.topology import load_topology

    out = []
    for name, region, x0r, x1r, z0r, hr, out_y, prob in PHOTO_DETAILS:
        if rng.random() >= prob:
            continue
        reg = [m for m in meshes if m.name == region]
        x0, x1, z0 = rng.uniform(*x0r), rng.uniform(*x1r), rng.uniform(*z0r)
        patch = _surface_patch(name, reg, x0, x1, z0, min(z0 + rng.uniform(*hr), 1.0), out_y) if reg else None
        if patch is not None:
            out.append(patch)
    topo = load_topology()
    cp = np.asarray(control_points_mm, dtype=float)
    corner = cp[topo.junction_point_index("window_front_bottom")]
    half_width = float(cp[:, 0].max())
    length, height = rng.uniform(90, 150), rng.uniform(100, 150)
    y0 = corner[1] + rng.uniform(40, 160)
    z0 = corner[2] - rng.uniform(0, 40)
    out.append(_box_mesh("mirror", np.array([corner[0] - 20.0, y0, z0]),
                         np.array([half_width + rng.uniform(150, 220), y0 + length, z0 + height])))
    return out + mirrored(out)


#: Names of the detail meshes (either kind): what :func:`classic_meshes` takes away.
DETAIL_NAMES = ("headlight", "grille", "plate", "taillight", "mirror")


def classic_meshes(meshes):
    """A body's meshes with the fixed :data:`DETAILS` of the classic renders in place of whatever
    details it carries (the photo-like ones of :func:`photo_detail_meshes`)."""
    bare = [m for m in meshes if m.name not in DETAIL_NAMES]
    return bare + detail_meshes(bare)


def body_meshes(spec: BodySpec, surface_body: Callable | None = None, photo_details: bool = False,
                seed: int = 0):
    """Tessellated body (both halves, region names) plus wheels, lamps and grille, mm; with
    ``photo_details`` the lamps, grilles and mirrors of :func:`photo_detail_meshes` (drawn from
    ``seed`` and the body's name) instead of the fixed :data:`DETAILS`."""
    from carbody.render import tessellate
    from carbody.wireframe import Wireframe

    wireframe = Wireframe(spec.body_id, spec.control_points_mm)
    if surface_body is None:
        try:
            from carbody.surface import build_body
        except ImportError:
            raise ViewError("the data set needs surfaced bodies, and carbody.surface is not "
                            "available in this installation") from None
        body = build_body(wireframe, check=False)
    else:
        body = surface_body(wireframe)
    meshes = tessellate(body)
    if photo_details:
        import zlib

        rng = np.random.default_rng([seed, 6, zlib.crc32(spec.body_id.encode())])
        details = photo_detail_meshes(meshes, spec.control_points_mm, rng)
    else:
        details = detail_meshes(meshes)
    return meshes + wheel_meshes(spec.control_points_mm, spec.tyre_radius_mm) + details


# ----------------------------------------------------------------------------------------- looks

def random_background(rng: np.random.Generator, size: int = IMAGE_SIZE) -> tuple[np.ndarray, str]:
    """A (size, size, 3) uint8 background and its kind."""
    import cv2

    kind = str(rng.choice(["plain", "gradient", "street", "noise", "stripes"], p=[0.2, 0.15, 0.35, 0.15, 0.15]))
    h = w = size
    c1, c2 = rng.uniform(0, 1, 3), rng.uniform(0, 1, 3)
    if kind == "plain":
        grey = rng.uniform(0.4, 1.0)
        img = np.ones((h, w, 3)) * (grey * 0.7 + 0.3 * c1 if rng.random() < 0.5 else np.full(3, grey))
    elif kind == "gradient":
        t = np.linspace(0, 1, h)[:, None, None]
        img = np.broadcast_to(c1 * (1 - t) + c2 * t, (h, w, 3)).copy()
    elif kind == "street":
        horizon = int(h * rng.uniform(0.35, 0.75))
        sky = np.array([0.55, 0.7, 0.9]) * rng.uniform(0.6, 1.1) + rng.normal(0, 0.05, 3)
        ground = np.array([0.4, 0.4, 0.4]) * rng.uniform(0.5, 1.4) + rng.normal(0, 0.06, 3)
        img = np.empty((h, w, 3))
        img[:horizon] = sky
        img[horizon:] = ground
        for _ in range(rng.integers(0, 7)):   # buildings, trees, other cars: blocks on the horizon
            x0 = rng.integers(0, w)
            bw, bh = rng.integers(w // 12, w // 3), rng.integers(h // 10, int(h * 0.6))
            img[max(0, horizon - bh):horizon, x0:x0 + bw] = rng.uniform(0.1, 0.9, 3)
        if rng.random() < 0.5:                 # kerb or road marking
            y = rng.integers(horizon, h)
            img[y:y + rng.integers(1, 4)] = rng.uniform(0.6, 1.0)
    elif kind == "noise":
        small = rng.uniform(0, 1, (rng.integers(3, 12), rng.integers(3, 12), 3))
        img = cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
    else:
        period = rng.uniform(6, 40)
        ang = rng.uniform(0, np.pi)
        yy, xx = np.mgrid[0:h, 0:w]
        s = (np.sin((xx * np.cos(ang) + yy * np.sin(ang)) * 2 * np.pi / period) > 0)[..., None]
        img = np.where(s, c1, c2)
    img = img + rng.normal(0, rng.uniform(0, 0.04), img.shape)
    return (np.clip(img, 0, 1) * 255).astype(np.uint8), kind


#: Colours of wheels, lamps and grille when colour variation is off (and for tests).
FIXED_DETAIL_COLOURS = {"tyre": (0.06, 0.06, 0.06), "rim": (0.6, 0.6, 0.6), "underbody": (0.03, 0.03, 0.03),
                        "headlight": (0.85, 0.85, 0.82), "grille": (0.08, 0.08, 0.08), "taillight": (0.75, 0.05, 0.05)}


@dataclass
class Shot:
    """Everything about one image but the body (all angles in degrees)."""

    class_index: int
    theta_deg: float          # the true view of the (possibly mirrored) picture
    render_theta_deg: float   # the left-side view rendered before any flip
    mirrored: bool
    elevation_deg: float
    roll_deg: float
    distance_lengths: float   # perspective camera distance in car lengths; 0 = orthographic
    fill: float
    offset: tuple[float, float]
    background: str
    paint: tuple[float, float, float]
    box: tuple[float, float, float, float] | None = None   # the car's box (x0, y0, x1, y1), pixels


def sample_shot(rng: np.random.Generator, class_index: int, vary: Variation):
    """A random :class:`Shot` of class ``class_index`` and its :class:`carbody.render.Look`."""
    from carbody.render import Look

    theta = (CLASS_ANGLES_DEG[class_index] + rng.uniform(-1, 1) * vary.angle_jitter_deg) % 360.0
    # right-side views are mirror images; exact 0° / 180° views are flipped half the time
    mirrored = theta > 180.0 or (theta in (0.0, 180.0) and rng.random() < 0.5)
    render_theta = 360.0 - theta if mirrored else theta
    if vary.elevation:
        elevation = rng.uniform(0.0, 30.0)
        roll = rng.normal(0.0, 2.5)
        distance = 0.0 if rng.random() < 0.25 else rng.uniform(1.6, 6.0)
        fill = rng.uniform(0.6, 0.95) if rng.random() < 0.85 else rng.uniform(0.95, 1.15)
        offset = tuple(rng.uniform(-0.08, 0.08, 2))
    else:
        elevation, roll, distance, fill, offset = 10.0, 0.0, 0.0, 0.85, (0.0, 0.0)
    if vary.colour:
        paint = np.clip(PAINT_PALETTE[rng.integers(len(PAINT_PALETTE))] + rng.normal(0, 0.05, 3), 0, 1)
        glass = np.clip(np.array([0.06, 0.08, 0.1]) * rng.uniform(0.5, 2.5) + rng.normal(0, 0.02, 3), 0, 1)
        light = dict(light_azimuth_deg=rng.uniform(-80, 80), light_elevation_deg=rng.uniform(-10, 70),
                     light_intensity=rng.uniform(0.5, 1.1), ambient=rng.uniform(0.1, 0.45),
                     specular=rng.uniform(0.1, 0.7))
        colours = {"tyre": tuple(np.full(3, rng.uniform(0.03, 0.12))),
                   "rim": tuple(np.full(3, rng.uniform(0.3, 0.85))), "underbody": (0.03, 0.03, 0.03),
                   "headlight": tuple(np.clip(rng.uniform(0.6, 0.95) + rng.normal(0, 0.03, 3), 0, 1)),
                   "grille": tuple(np.full(3, rng.uniform(0.02, 0.25))),
                   "taillight": (rng.uniform(0.5, 0.9), rng.uniform(0.0, 0.1), rng.uniform(0.0, 0.1))}
    else:
        paint, glass = np.array([0.72, 0.73, 0.75]), np.array([0.07, 0.09, 0.11])
        light = {}
        colours = dict(FIXED_DETAIL_COLOURS)
    if vary.background:
        background, kind = random_background(rng)
    else:
        background, kind = (1.0, 1.0, 1.0), "white"
    look = Look(paint=tuple(paint), glass=tuple(glass), colours=colours, background=background, **light)
    shot = Shot(class_index, float(theta), float(render_theta), bool(mirrored), float(elevation), float(roll),
                float(distance), float(fill), (float(offset[0]), float(offset[1])), kind,
                tuple(float(v) for v in paint))
    return shot, look


def shoot(scene, shot: Shot, look, car_length: float, rng: np.random.Generator, vary: Variation) -> np.ndarray:
    """Render one :class:`Shot` of a scene: (IMAGE_SIZE, IMAGE_SIZE, 3) uint8."""
    import cv2

    img = scene.render(shot.render_theta_deg, shot.elevation_deg, shot.roll_deg, look=look,
                       distance=shot.distance_lengths * car_length or None, fill=shot.fill,
                       offset=shot.offset)
    if shot.mirrored:
        img = img[:, ::-1].copy()
    if vary.colour or vary.background:   # camera blur and sensor noise
        if rng.random() < 0.4:
            img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.3, 1.2))
        sigma = rng.uniform(0, 6)
        img = np.clip(img + rng.normal(0, sigma, img.shape), 0, 255).astype(np.uint8)
    return img


def shoot_photo(scene, spec: BodySpec, class_index: int, rng: np.random.Generator, vary: Variation):
    """One photo-like shot (:mod:`carbody.view.photo`) of class ``class_index``: (Shot, image)."""
    from carbody.render import Look
    from carbody.view import photo as ph

    pl = vary.photo
    theta = (CLASS_ANGLES_DEG[class_index] + rng.uniform(-1, 1) * vary.angle_jitter_deg) % 360.0
    mirrored = theta > 180.0 or (theta in (0.0, 180.0) and rng.random() < 0.5)
    render_theta = 360.0 - theta if mirrored else theta
    lo, hi = scene.bounds
    car_length = float(hi[1] - lo[1])
    ground_z = -float(spec.tyre_radius_mm)
    if pl.camera:
        elevation, dist = ph.person_camera(rng, lo, hi, ground_z, scene.radius,
                                           render_theta if pl.framing else None)
    else:
        elevation, dist = rng.uniform(0.0, 30.0), max(rng.uniform(1.6, 6.0) * car_length, 1.15 * scene.radius)
    roll = rng.normal(0.0, 1.5)
    if pl.framing:     # room around the car for the photo's frame and the crop (photo_frame_crop)
        fill = rng.uniform(0.6, 0.78)
        offset = tuple(rng.uniform(-0.03, 0.03, 2))
    else:
        fill = rng.uniform(0.62, 0.95) if rng.random() < 0.9 else rng.uniform(0.95, 1.1)
        offset = tuple(rng.uniform(-0.05, 0.05, 2))
    paint, glass, colours, env = ph.photo_looks(rng, pl)
    look = Look(paint=tuple(paint), glass=tuple(glass), colours=colours, background=(0.0, 0.0, 0.0),
                environment=env, light_azimuth_deg=rng.uniform(-80, 80), light_elevation_deg=rng.uniform(10, 70),
                light_intensity=rng.uniform(0.6, 1.1), ambient=rng.uniform(0.15, 0.4), specular=rng.uniform(0.2, 0.6))
    if pl.tone:
        look = ph.linear_look(look)
    premult, alpha = scene.render(render_theta, elevation, roll, look=look, distance=dist, fill=fill,
                                  offset=offset, return_alpha=True)
    if pl.tone:
        premult = ph.display_encode(premult, alpha, rng.uniform(0.85, 1.3))
    if pl.backdrop:
        back, kind = ph.backdrop(rng, IMAGE_SIZE, pl.sharp), "photo"
    else:
        back, kind = random_background(rng)
        back = back.astype(np.float32) / 255.0
    bg = ph.ground_and_shadow(scene, rng, ground_z, lo, hi, back, pl.ground)
    img = premult.astype(np.float32) / 255.0 + (1 - alpha[..., None]) * bg
    img = np.clip(img * 255 + 0.5, 0, 255).astype(np.uint8)
    if mirrored:
        img = img[:, ::-1].copy()
        alpha = alpha[:, ::-1]
    if pl.artefacts:
        img = ph.artefacts(img, rng, pl.sharp)
    else:
        img = np.clip(img + rng.normal(0, rng.uniform(0, 4), img.shape), 0, 255).astype(np.uint8)
    box = None
    if pl.framing:
        rows, cols = np.nonzero(alpha > 0.5)
        if len(rows):
            box = (float(cols.min()), float(rows.min()), float(cols.max() + 1), float(rows.max() + 1))
    shot = Shot(class_index, float(theta), float(render_theta), bool(mirrored), float(elevation), float(roll),
                float(dist / car_length), float(fill), (float(offset[0]), float(offset[1])), kind,
                tuple(float(v) for v in paint), box)
    return shot, img


# ----------------------------------------------------------------------------------------- writer

MANIFEST_FIELDS = ["file", "class_index", "class_deg", "theta_deg", "elevation_deg", "roll_deg", "mirrored",
                   "distance_lengths", "fill", "background", "body", "template", "model_index", "split", "box"]


def row_box(row: dict) -> tuple[float, float, float, float] | None:
    """The car's box (x0, y0, x1, y1) pixels of a manifest row (framed photo-like renders), else None."""
    text = (row.get("box") or "").strip()
    return tuple(float(v) for v in text.split()) if text else None  # type: ignore[return-value]


def split_templates(names: list[str], seed: int, fraction: float = VALIDATION_FRACTION) -> set[str]:
    """The templates whose bodies are validation (seeded, at least one)."""
    rng = np.random.default_rng([seed, 2])
    n = max(1, int(round(fraction * len(names))))
    return {names[i] for i in rng.choice(len(names), size=n, replace=False)}


#: Images one task renders (a Scene built per such chunk, here and on a cluster alike, so the
#: images do not depend on how the work is spread).
IMAGES_PER_TASK = 64


def render_dataset(out_dir: str | Path, count: int = DEFAULT_COUNT, seed: int = 0,
                   bodies_per_template: int = 4, vary: Variation = Variation(),
                   templates: list[str] | None = None, progress: bool = True,
                   surface_body: Callable | None = None, client=None, blends: int = 0) -> Path:
    """Render the data set into ``out_dir`` (see module docstring); returns the manifest path.

    Args:
        count: number of images (spread evenly over bodies and the 24 classes).
        seed: everything random follows from it.
        bodies_per_template: the template itself plus this many − 1 library expansions.
        vary: what varies between images.
        templates: restrict to these template names (default all).
        blends: this many more bodies, each a random mix of two training templates
            (:func:`blend_bodies`), all in the training split.
        surface_body: ``Wireframe -> Body`` (default :func:`carbody.surface.build_body`; on a
            cluster it must pickle: a module-level function).
        client: a ``distributed.Client`` (:func:`carbody.cluster.connect`) to surface the bodies
            and render their images on, every worker writing into ``out_dir`` (which they must
            see); None: in this process. The files are the same bit for bit either way, for any
            number of workers: each image's randomness follows from (seed, body, image) alone,
            and each chunk of :data:`IMAGES_PER_TASK` gets a scene of its own.

    Raises:
        ViewError: bad count, unknown template, an output folder that already holds a data set.
    """
    from tqdm import tqdm

    from carbody.library import load_library
    from carbody.progress import bar_disabled
    from carbody.templates import load_templates

    if count < N_CLASSES:
        raise ViewError(f"--count must be at least {N_CLASSES} (one image per class), got {count}")
    if bodies_per_template < 1:
        raise ViewError("bodies per template must be at least 1")
    out = Path(out_dir)
    if (out / "manifest.csv").exists():
        raise ViewError(f"{out} already holds a data set (manifest.csv); choose an empty folder")
    library = load_library()
    rows = [row for row, _ in load_templates()]
    bodies = choose_bodies(library, rows, bodies_per_template, seed)
    if templates:
        unknown = set(templates) - set(library.template_names)
        if unknown:
            raise ViewError(f"unknown template {sorted(unknown)[0]!r}")
        bodies = [b for b in bodies if b.template in templates]
    val_templates = split_templates(sorted({b.template for b in bodies}), seed)
    if blends:     # mixes of training templates only, so no held-out car leaks into training
        bodies += blend_bodies(library, rows, sorted({b.template for b in bodies} - val_templates), blends, seed)

    # Spread images: body b gets count // n (+1 for the first count % n), classes cycled.
    per_body = [count // len(bodies) + (i < count % len(bodies)) for i in range(len(bodies))]
    (out / "images").mkdir(parents=True, exist_ok=True)
    skipped: list[dict] = []
    bar = tqdm(total=count, desc="render-dataset", unit="img", disable=bar_disabled(not progress))
    if client is None:
        manifest_rows = _render_here(out, bodies, per_body, seed, vary, val_templates, surface_body, skipped, bar)
    else:
        manifest_rows = _render_on(client, out, bodies, per_body, seed, vary, val_templates, surface_body,
                                   skipped, bar)
    bar.close()
    tmp = out / ".manifest.csv.tmp"
    with open(tmp, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=MANIFEST_FIELDS)
        writer.writeheader()
        writer.writerows(manifest_rows)
    (out / "dataset.json").write_text(json.dumps({
        "count": len(manifest_rows), "seed": seed, "image_size": IMAGE_SIZE, "classes_deg": CLASS_ANGLES_DEG.tolist(),
        "bodies": [b.body_id for b in bodies if b.body_id not in {k["body"] for k in skipped}],
        "skipped_bodies": skipped, "validation_templates": sorted(val_templates),
        "variation": asdict(vary), "bodies_per_template": bodies_per_template, "blends": blends}, indent=1))
    tmp.replace(out / "manifest.csv")
    return out / "manifest.csv"


def surfaced_meshes(spec: BodySpec, surface_body: Callable | None = None, vary: Variation = Variation(),
                    seed: int = 0) -> tuple[list | None, str | None]:
    """(:func:`body_meshes`, None), or (None, why) when the body cannot be surfaced.

    Any failure (a refused region or a bug in a surfacing stage) only skips the body, recorded in
    dataset.json: one bad expansion must not stop a 3000-image render.
    """
    try:
        return body_meshes(spec, surface_body, vary.photo is not None and vary.photo.details, seed), None
    except Exception as exc:  # noqa: BLE001  see above
        return None, f"{type(exc).__name__}: {exc}"


def _failure(surfaced: tuple[list | None, str | None]) -> str | None:
    return surfaced[1]


def _render_surfaced(out, spec, b, surfaced, images, seed, vary, split) -> list[dict]:
    return render_images(out, spec, b, surfaced[0], images, seed, vary, split)


def image_plan(bodies: list[BodySpec], per_body: list[int], failure: Callable[[int], str | None],
               skipped: list[dict]):
    """(body index, number of images) for each body that surfaces, in order: a body that does not
    (``failure(b)`` says why; asked in order, as the work goes) is recorded in ``skipped`` and
    its images go to the next body.

    Raises:
        ViewError: the last body cannot be surfaced.
    """
    carry = 0
    for b, (spec, n_img) in enumerate(zip(bodies, per_body)):
        n_img += carry
        reason = failure(b)
        if reason is not None:
            if b == len(bodies) - 1:
                raise ViewError(f"the last body {spec.body_id} cannot be surfaced: {reason}")
            skipped.append({"body": spec.body_id, "reason": reason})
            carry = n_img
            continue
        carry = 0
        yield b, n_img


def image_chunks(b: int, n_img: int, seed: int) -> list[list[tuple[int, int]]]:
    """Body ``b``'s images as chunks of :data:`IMAGES_PER_TASK` (image index, class index)."""
    brng = np.random.default_rng([seed, 3, b])
    classes = (np.arange(n_img) + brng.integers(N_CLASSES)) % N_CLASSES
    brng.shuffle(classes)
    images = [(i, int(k)) for i, k in enumerate(classes)]
    return [images[s:s + IMAGES_PER_TASK] for s in range(0, len(images), IMAGES_PER_TASK)]


def render_images(out: str | Path, spec: BodySpec, b: int, meshes, images: list[tuple[int, int]], seed: int,
                  vary: Variation, split: str) -> list[dict]:
    """Render body ``b``'s ``images`` ((image index, class index)) into ``out/images/<θ>/`` on a
    scene of their own; returns their manifest rows."""
    from carbody.render import Scene, save_png

    out = Path(out)
    scene = Scene(meshes, size=(IMAGE_SIZE, IMAGE_SIZE), antialias=2)
    classic_scene = None
    car_length = float(np.ptp(spec.control_points_mm[:, 1]))
    rows = []
    for i, k in images:
        rng = np.random.default_rng([seed, 4, b, i])
        if vary.photo is None or rng.random() >= vary.photo_fraction:
            shot, look = sample_shot(rng, k, vary)
            if vary.classic_details and vary.photo is not None and vary.photo.details:
                if classic_scene is None:   # the classic share looks as classic renders do
                    classic_scene = Scene(classic_meshes(meshes), size=(IMAGE_SIZE, IMAGE_SIZE), antialias=2)
                img = shoot(classic_scene, shot, look, car_length, rng, vary)
            else:
                img = shoot(scene, shot, look, car_length, rng, vary)
        else:
            shot, img = shoot_photo(scene, spec, k, rng, vary)
        rel = Path("images") / f"{int(CLASS_ANGLES_DEG[k]):03d}" / f"{spec.body_id}_{i:04d}.png"
        (out / rel).parent.mkdir(exist_ok=True)
        save_png(img, out / rel)
        rows.append({
            "file": rel.as_posix(), "class_index": int(k), "class_deg": int(CLASS_ANGLES_DEG[k]),
            "theta_deg": round(shot.theta_deg, 3), "elevation_deg": round(shot.elevation_deg, 3),
            "roll_deg": round(shot.roll_deg, 3), "mirrored": int(shot.mirrored),
            "distance_lengths": round(shot.distance_lengths, 3), "fill": round(shot.fill, 3),
            "background": shot.background, "body": spec.body_id, "template": spec.template,
            "model_index": spec.model_index, "split": split,
            "box": "" if shot.box is None else " ".join(f"{v:g}" for v in shot.box)})
    return rows


def _render_here(out, bodies, per_body, seed, vary, val_templates, surface_body, skipped, bar) -> list[dict]:
    """Body after body in this process: each surfaced, then its images rendered."""
    meshes: dict[int, list] = {}

    def failure(b: int) -> str | None:
        bar.set_postfix_str(bodies[b].body_id)
        meshes[b], reason = surfaced_meshes(bodies[b], surface_body, vary, seed)
        return reason

    rows = []
    for b, n_img in image_plan(bodies, per_body, failure, skipped):
        split = "val" if bodies[b].template in val_templates else "train"
        for chunk in image_chunks(b, n_img, seed):
            rows += render_images(out, bodies[b], b, meshes[b], chunk, seed, vary, split)
            bar.update(len(chunk))
        del meshes[b]
    return rows


def _render_on(client, out, bodies, per_body, seed, vary, val_templates, surface_body, skipped, bar) -> list[dict]:
    """On a Dask cluster: every body surfaced at once (its meshes stay on the worker that made
    them), then every chunk of images rendered where its body's meshes are; rows in the order
    this process would write them."""
    from distributed import as_completed

    from carbody.cluster import check_shared_folder

    check_shared_folder(client, out)
    bar.set_postfix_str(f"surfacing {len(bodies)} bodies")
    surfaced = [client.submit(surfaced_meshes, spec, surface_body, vary, seed, pure=False) for spec in bodies]
    failures = client.gather([client.submit(_failure, s, pure=False) for s in surfaced])
    tasks = {}
    for b, n_img in image_plan(bodies, per_body, failures.__getitem__, skipped):
        split = "val" if bodies[b].template in val_templates else "train"
        for chunk in image_chunks(b, n_img, seed):
            future = client.submit(_render_surfaced, str(out), bodies[b], b, surfaced[b], chunk, seed, vary, split,
                                   pure=False)
            tasks[future] = (b, chunk[0][0])
    bar.set_postfix_str("")
    chunks = {}
    for future in as_completed(tasks):
        chunks[tasks[future]] = future.result()
        bar.update(len(chunks[tasks[future]]))
    del surfaced
    return [row for key in sorted(chunks) for row in chunks[key]]


def dataset_folders(dataset_dirs) -> list[Path]:
    """The folders of one data set (a path) or of several trained on together (a list)."""
    return [Path(dataset_dirs)] if isinstance(dataset_dirs, (str, Path)) else [Path(d) for d in dataset_dirs]


def read_datasets(dataset_dirs) -> list[dict]:
    """Rows of one data set (:func:`read_manifest`) or of several trained on together (a list of
    folders; each row's ``file`` then names its image by absolute path).

    Several data sets must split their cars alike (their ``dataset.json``'s validation templates):
    else a car one of them holds out would be trained on from another.

    Raises:
        ViewError: a folder as :func:`read_manifest` refuses it, or data sets split differently.
    """
    import json

    dirs = dataset_folders(dataset_dirs)
    if not dirs:
        raise ViewError("no data set folder given")
    if len(dirs) == 1:
        return read_manifest(dirs[0])
    rows, splits = [], {}
    for d in dirs:
        for r in read_manifest(d):
            r["file"] = str((d / r["file"]).resolve())
            rows.append(r)
        meta = d / "dataset.json"
        splits[d] = sorted(json.loads(meta.read_text()).get("validation_templates", [])) if meta.exists() else None
    if len({tuple(v) for v in splits.values() if v is not None}) > 1:
        raise ViewError(f"the data sets {', '.join(map(str, dirs))} hold out different cars for validation "
                        f"(render them with the same --seed and templates): trained together, one would "
                        f"train on a car another holds out")
    return rows


def read_manifest(dataset_dir: str | Path) -> list[dict]:
    """Rows of a data set: ``manifest.csv`` if present, else a folder of class folders named by
    angle (``0``, ``15``, ... ``345`` or ``000``..), split 8:2 at random by image (seed 0).

    Raises:
        ViewError: no such folder, no images, a class folder that is not an angle.
    """
    root = Path(dataset_dir)
    if not root.is_dir():
        raise ViewError(f"{root}: no such data set folder")
    if (root / "manifest.csv").exists():
        with open(root / "manifest.csv", newline="") as fh:
            rows = list(csv.DictReader(fh))
        for r in rows:
            r["class_index"] = int(r["class_index"])
        if not rows:
            raise ViewError(f"{root}/manifest.csv lists no images")
        return rows
    from carbody.view.labels import class_of

    base = root / "images" if (root / "images").is_dir() else root
    rows = []
    for folder in sorted(p for p in base.iterdir() if p.is_dir()):
        try:
            theta = float(folder.name)
        except ValueError:
            raise ViewError(f"{folder}: class folders must be named by angle in degrees") from None
        if theta % 15:
            raise ViewError(f"{folder}: {theta:g}° is not a 15° class")
        for f in sorted(folder.iterdir()):
            if f.suffix.lower() in (".png", ".jpg", ".jpeg", ".bmp", ".webp"):
                rows.append({"file": str(f.relative_to(root)), "class_index": class_of(theta), "body": f.stem})
    if not rows:
        raise ViewError(f"{root}: no images found (need manifest.csv or class folders of images)")
    rng = np.random.default_rng(0)
    val = set(rng.choice(len(rows), size=max(1, len(rows) // 5), replace=False).tolist())
    for i, r in enumerate(rows):
        r["split"] = "val" if i in val else "train"
    return rows
