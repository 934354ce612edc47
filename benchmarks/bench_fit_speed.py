"""Speed of the single-view solve (issue 3): one solve over the shipped library (252 models per
template), scaling to 35k, 350k and 1M models, the full fit with view refinement, and scipy's
nnls / lsq_linear on the same problems.

Larger libraries are the same templates expanded with finer factors (the library's own
``expand``), keeping only the 35 keypoint rows of each model (float32): 1M models x 105 rows is
0.4 GB where the full S would be 6.7 GB. A "solve" is everything after the keypoints are read:
projection rows for the view, the active-set NNLS over the whole library, scale and offset.

Run: python benchmarks/bench_fit_speed.py [--max-models 1000000]
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np


def median_time(fn, repeat: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), out


def keypoints_of_expanded_library(n_per_axis: tuple[int, int, int]) -> np.ndarray:
    """(35, 3, N) float32 keypoints of the templates expanded with evenly spaced finer factors."""
    from carbody.library import Expansion, expand, load_library, normalise
    from carbody.templates import load_templates
    from carbody.topology import load_topology

    nh, nf, nw = n_per_axis

    def factors(lo, hi, n):
        f = np.linspace(lo, hi, n + 1)
        return tuple(float(x) for x in f if abs(x - 1.0) > 1e-9)[:n]

    exp = Expansion(height=factors(0.7, 1.2, nh), front_overhang=factors(0.8, 1.1, nf),
                    rear_overhang=factors(0.8, 1.1, nf), width=factors(0.7, 1.2, nw))
    topo = load_topology()
    idx = topo.keypoint_point_indices
    base = np.array([normalise(w.control_points, topo) for _, w in load_templates()])
    parts = []
    for t in range(len(base)):
        pts, _, _ = expand(base[t:t + 1], exp, topo)
        parts.append(np.ascontiguousarray(pts[:, idx, :].transpose(1, 2, 0), dtype=np.float32))
        del pts
    load_library  # the shipped library is built by the same expand
    return np.concatenate(parts, axis=2)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-models", type=int, default=1_000_000)
    args = ap.parse_args(argv)

    from scipy.optimize import lsq_linear, nnls

    from carbody.camera import View, project
    from carbody.fit.shape_prior import prepared
    from carbody.fit.single_view import fit_wireframe
    from carbody.fit.solve import KeypointBasis, _centred, solve_gauss, solve_simplex
    from carbody.fit.visibility import visible_slots
    from carbody.library import load_library
    from carbody.topology import load_topology

    lib = load_library()
    idx = load_topology().keypoint_point_indices
    name = "Toyota Camry XV70"
    truth = lib.points(lib.original(name)) * [1.05, 0.98, 1.03]  # a car near, not in, the library
    view = View(30)
    slots = visible_slots(view, truth)
    rng = np.random.default_rng(0)
    uv = project(np.array([truth[s.point_index] * s.sign for s in slots]), view, 0.45, (500, 300)) \
        + rng.normal(0, 1, (len(slots), 2))
    kps = {s.name: p for s, p in zip(slots, uv)}
    print(f"# Single-view solve speed ({len(slots)} keypoints, view 30°; 2-core machine)\n")

    basis = KeypointBasis.from_shapes(lib.S, idx)
    t_ours, sol = median_time(lambda: solve_simplex(basis, slots, uv, view), 50)
    M, _, Mc, _, z, b, rho = _centred(slots, uv, view)
    A = (Mc @ basis.X.reshape(105, -1)) / basis.size
    t_nnls, (x_nnls, r_nnls) = median_time(lambda: nnls(A, b), 5)
    t_bvls, res_bvls = median_time(lambda: lsq_linear(A, b, bounds=(0, np.inf), method="bvls"), 3)
    t_trf, res_trf = median_time(lambda: lsq_linear(A, b, bounds=(0, np.inf), method="trf", tol=1e-12,
                                                    max_iter=2000), 1)
    ours_cost = float(np.sqrt(sol.cost))
    print(f"## One constrained solve (ΣH = 1, 0 ≤ H ≤ 1) at {lib.n_models} models\n")
    print("| solver | ms (median) | residual ‖K·G − z‖ (rel.) |")
    print("|---|---|---|")
    print(f"| carbody active set (incl. projection rows, scale, offset) | {t_ours * 1e3:.2f} | {ours_cost:.6g} |")
    print(f"| scipy.optimize.nnls (same centred matrix) | {t_nnls * 1e3:.2f} | {r_nnls:.6g} |")
    print(f"| scipy.optimize.lsq_linear bvls | {t_bvls * 1e3:.2f} | {np.linalg.norm(A @ res_bvls.x - b):.6g} |")
    print(f"| scipy.optimize.lsq_linear trf | {t_trf * 1e3:.2f} | {np.linalg.norm(A @ res_trf.x - b):.6g} |")

    model = prepared(lib, "gauss")
    t_gauss, _ = median_time(lambda: solve_gauss(model, idx, slots, uv, view), 50)
    t_mix, _ = median_time(lambda: solve_gauss(model, idx, slots, uv, view, mixture=True), 50)
    print(f"\nGaussian-prior solves at {lib.n_models} models (median of 50): mixture (default) {t_mix * 1e3:.2f} ms, "
          f"gauss {t_gauss * 1e3:.2f} ms")
    t0 = time.perf_counter()
    prepared.__globals__["_PREPARED"].clear()
    built = prepared(lib, "gauss")
    library_part = prepared(lib, "gauss", field=False).basis.shape[1]
    print(f"Shape model build (once per library, PCA of S): {time.perf_counter() - t0:.2f} s; "
          f"{library_part} library directions "
          f"({prepared(lib, 'gauss', 2650.0, field=False).basis.shape[1]} sized in mm, wheelbase told) "
          f"and {built.basis.shape[1] - library_part} of the joint field")

    print(f"\n## Full fit with view refinement at {lib.n_models} models (given view 30°; median of 5)\n")
    print("| method | camera | s | refined azimuth |")
    print("|---|---|---|---|")
    for method, wheelbase in (("gauss", None), ("mixture", None), ("paper", None), ("mixture", 2650.0)):
        for camera in (None, "auto"):
            fit_wireframe(kps, 30, lib, method=method, wheelbase_mm=wheelbase)  # prepares the library once
            tt, res = median_time(lambda: fit_wireframe(kps, 30, lib, method=method, wheelbase_mm=wheelbase,
                                                         camera_distance_mm=camera), 5)
            label = "orthographic" if camera is None else "distance found (auto)"
            told = "" if wheelbase is None else f", wheelbase told ({wheelbase:g} mm)"
            print(f"| {method}{told} | {label} | {tt:.3f} | {res.view.azimuth:.1f}° |")
    print("\n## Scaling (paper solve; finer expansion factors; keypoint rows only, float32)\n")
    print("| models | build s | solve ms (median of 3, cold start) | solve ms warm start | scipy nnls ms | residual ours / nnls |")
    print("|---|---|---|---|---|---|")
    for n_axes in ((9, 7, 16), (19, 17, 35), (29, 24, 48)):
        t0 = time.perf_counter()
        X = keypoints_of_expanded_library(n_axes)
        n = X.shape[2]
        if n > args.max_models * 1.05:
            break
        big = KeypointBasis.from_keypoints(X)
        build = time.perf_counter() - t0
        solve_simplex(big, slots, uv, view)  # warm-up (page faults)
        tt, s_big = median_time(lambda: solve_simplex(big, slots, uv, view), 3)
        tw, _ = median_time(lambda: solve_simplex(big, slots, uv, view, warm_support=s_big.support), 3)
        scipy_cell, ratio = "—", "—"
        if n <= 40_000:
            Ab = (Mc @ big.X.reshape(105, -1).astype(np.float64)) / big.size
            ts, (xs, rs) = median_time(lambda: nnls(Ab, b), 1)
            scipy_cell, ratio = f"{ts * 1e3:.0f}", f"{np.sqrt(s_big.cost) / rs:.6f}"
        print(f"| {n:,} | {build:.1f} | {tt * 1e3:.1f} | {tw * 1e3:.1f} | {scipy_cell} | {ratio} |")
        del X, big
    return 0


if __name__ == "__main__":
    sys.exit(main())
