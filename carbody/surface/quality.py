"""Surface quality figures, measured on the Bezier nets themselves (numpy, no OCCT).

* **G0 gap**: distance between the two faces' points at the same place of a shared edge.
* **G1 angle**: angle between the two faces' normals there (degrees).
* **scaled Jacobian** of a quad net: at each corner of each control quad, the cross product of
  its two edges over the product of their lengths, signed by the face normal; 1 for a square,
  0 for a degenerate quad, negative for a fold; the same measure on the surface itself
  (S_u x S_v against the face's mean normal, on a grid) tells whether the face really folds.

Shared edges are found from the faces' side references: inside a region, consecutive faces
share a rib; across regions (and the symmetry plane), faces whose sides lie on the same
wireframe curve overlap on a common curve-parameter interval.
"""
from __future__ import annotations

import functools
from collections import defaultdict

import numpy as np

from carbody.surface.control_net import FacePatch

_SAMPLES = 11


def _bern(t: np.ndarray) -> np.ndarray:
    t = np.asarray(t, float)[..., None]
    return np.concatenate([(1 - t) ** 3, 3 * (1 - t) ** 2 * t, 3 * (1 - t) * t**2, t**3], axis=-1)


def _dbern(t: np.ndarray) -> np.ndarray:
    t = np.asarray(t, float)[..., None]
    return np.concatenate([-3 * (1 - t) ** 2, 3 * (1 - t) ** 2 - 6 * t * (1 - t), 6 * t * (1 - t) - 3 * t**2,
                           3 * t**2], axis=-1)


def surface_points(net: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Points S(u_k, v_k) of a bicubic net (4, 4, 3); u, v (m,) -> (m, 3)."""
    return np.einsum("mi,mj,ijd->md", _bern(u), _bern(v), net)


def surface_normals(net: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit normals S_u x S_v (m, 3) at (u_k, v_k)."""
    su = np.einsum("mi,mj,ijd->md", _dbern(u), _bern(v), net)
    sv = np.einsum("mi,mj,ijd->md", _bern(u), _dbern(v), net)
    n = np.cross(su, sv)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def _side_uv(side: str, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    one, zero = np.ones_like(p), np.zeros_like(p)
    return {"v0": (p, zero), "v1": (p, one), "u0": (zero, p), "u1": (one, p)}[side]


def _angle(n1: np.ndarray, n2: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.abs((n1 * n2).sum(axis=-1)), -1, 1)))


def _seam_figures(nets_f: np.ndarray, uf: np.ndarray, vf: np.ndarray, nets_g: np.ndarray, ug: np.ndarray,
                  vg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(P,) largest G0 gap (mm) and G1 angle (deg) between faces f and g of P pairs at the same
    places: :func:`surface_points` and :func:`surface_normals` of every pair at once.

    Args:
        nets_f, nets_g: (P, 4, 4, 3) nets; uf, vf, ug, vg: (P, m) their parameters.
    """
    def points_normals(nets, u, v):
        bu, bv, du, dv = _bern(u), _bern(v), _dbern(u), _dbern(v)
        points = np.einsum("pmi,pmj,pijd->pmd", bu, bv, nets)
        n = np.cross(np.einsum("pmi,pmj,pijd->pmd", du, bv, nets), np.einsum("pmi,pmj,pijd->pmd", bu, dv, nets))
        return points, n / np.maximum(np.linalg.norm(n, axis=2, keepdims=True), 1e-300)

    pf, nf = points_normals(nets_f, uf, vf)
    pg, ng = points_normals(nets_g, ug, vg)
    return np.linalg.norm(pf - pg, axis=2).max(axis=1), _angle(nf, ng).max(axis=1)


def scaled_jacobian(net: np.ndarray) -> float:
    """Smallest scaled Jacobian over the corners of the 3 x 3 control quads of a net (4, 4, 3)."""
    n_ref = np.cross(net[3, 0] + net[3, 3] - net[0, 0] - net[0, 3], net[0, 3] + net[3, 3] - net[0, 0] - net[3, 0])
    n_ref /= np.linalg.norm(n_ref)
    q00, q10, q01, q11 = net[:-1, :-1], net[1:, :-1], net[:-1, 1:], net[1:, 1:]
    corners = [(q00, q10, q01), (q10, q11, q00), (q11, q01, q10), (q01, q00, q11)]
    worst = np.inf
    for c, a, b in corners:  # edges from corner c to a and to b, counter-clockwise
        ea, eb = a - c, b - c
        cr = np.cross(ea, eb) @ n_ref
        la, lb = np.linalg.norm(ea, axis=-1), np.linalg.norm(eb, axis=-1)
        sj = cr / np.maximum(la * lb, 1e-300)
        worst = min(worst, float(sj.min()))
    return worst


@functools.lru_cache(maxsize=4)
def _grid_bases(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The Bernstein bases and their derivatives at an n x n grid's u and v, (n², 4) each: the
    same for every face (read only)."""
    t = np.linspace(0, 1, n)
    u, v = (a.ravel() for a in np.meshgrid(t, t, indexing="ij"))
    bases = _bern(u), _bern(v), _dbern(u), _dbern(v)
    for b in bases:
        b.flags.writeable = False
    return bases


def surface_jacobian(net: np.ndarray, n: int = 9) -> float:
    """Smallest scaled Jacobian of the surface itself on an n x n grid: (S_u x S_v)·n̄ / (|S_u||S_v|),
    n̄ the face's mean normal; negative where the parametrisation folds over."""
    bu, bv, du, dv = _grid_bases(n)
    su = np.einsum("mi,mj,ijd->md", du, bv, net)
    sv = np.einsum("mi,mj,ijd->md", bu, dv, net)
    cr = np.cross(su, sv)
    mean = cr.sum(axis=0)
    mean /= np.linalg.norm(mean)
    lengths = np.linalg.norm(su, axis=1) * np.linalg.norm(sv, axis=1)
    return float((cr @ mean / np.maximum(lengths, 1e-300)).min())


def inner_seams(faces: list[FacePatch]) -> np.ndarray:
    """(len(faces) - 1, 2): max G0 gap (mm) and max G1 angle (deg) across each inner rib."""
    if len(faces) < 2:
        return np.zeros((0, 2))
    pairs = len(faces) - 1
    p = np.tile(np.linspace(0, 1, _SAMPLES), (pairs, 1))
    nets = np.array([f.net for f in faces])
    uf, vf = _side_uv("v1", p)
    ug, vg = _side_uv("v0", p)
    return np.stack(_seam_figures(nets[:-1], uf, vf, nets[1:], ug, vg), axis=1)


def seam_quality(faces: list[FacePatch]) -> dict[tuple[str, str], tuple[float, float]]:
    """{(region, region): (max G0 gap mm, max G1 angle deg)} along shared wireframe curves."""
    on_curve: dict[tuple[int, bool], list[tuple[FacePatch, str]]] = defaultdict(list)
    for f in faces:
        for side, ref in f.sides.items():
            if ref is not None:
                on_curve[ref.key].append((f, side))
    keys, nets, uv = [], ([], []), ([], [], [], [])
    for items in on_curve.values():
        for a in range(len(items)):
            for b in range(a + 1, len(items)):
                (f, sf), (g, sg) = items[a], items[b]
                if f.region == g.region and f.mirror == g.mirror:
                    continue
                rf, rg = f.sides[sf], g.sides[sg]
                lo = max(min(rf.t0, rf.t1), min(rg.t0, rg.t1))
                hi = min(max(rf.t0, rf.t1), max(rg.t0, rg.t1))
                if hi - lo <= 1e-9:
                    continue
                t = np.linspace(lo, hi, _SAMPLES)
                for where, (face, side, ref) in zip((0, 2), ((f, sf, rf), (g, sg, rg))):
                    u, v = _side_uv(side, (t - ref.t0) / (ref.t1 - ref.t0))
                    uv[where].append(u)
                    uv[where + 1].append(v)
                nets[0].append(f.net)
                nets[1].append(g.net)
                keys.append(tuple(sorted((f.region, g.region + ("_right" if g.mirror != f.mirror else "")))))
    out: dict[tuple[str, str], tuple[float, float]] = {}
    if not keys:
        return out
    gaps, angles = _seam_figures(np.array(nets[0]), np.array(uv[0]), np.array(uv[1]), np.array(nets[1]),
                                 np.array(uv[2]), np.array(uv[3]))
    for key, gap, ang in zip(keys, gaps.tolist(), angles.tolist()):
        old = out.get(key, (0.0, 0.0))
        out[key] = (max(old[0], gap), max(old[1], ang))
    return out


def region_report(faces: list[FacePatch], side_turn_deg: np.ndarray | None = None,
                  smooth_deg: float = 0.5) -> dict[str, float]:
    """Per-region figures of one region's (left-half) faces.

    ``inner_g1_deg`` is the largest normal angle across inner ribs whose ends sit where both
    sides are smooth (side turn below ``smooth_deg``; ``side_turn_deg`` per rib, (K,)); ribs
    ending at a corner of a side are reported apart (``corner_ribs``, ``corner_g1_deg``).
    """
    seams = inner_seams(faces)
    turn = np.zeros(len(faces) + 1) if side_turn_deg is None else np.asarray(side_turn_deg)
    corner = turn[1:-1] >= smooth_deg
    smooth = seams[~corner]
    return {"faces": len(faces),
            "inner_g0_mm": float(seams[:, 0].max()) if len(seams) else 0.0,
            "inner_g1_deg": float(smooth[:, 1].max()) if len(smooth) else 0.0,
            "corner_ribs": int(corner.sum()),
            "corner_g1_deg": float(seams[corner, 1].max()) if corner.any() else 0.0,
            "min_scaled_jacobian": min(scaled_jacobian(f.net) for f in faces),
            "min_surface_jacobian": min(surface_jacobian(f.net) for f in faces)}
