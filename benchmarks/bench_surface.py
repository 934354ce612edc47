"""Surfaces: speed per stage (wireframe STEP -> body STEP) and quality, against a plain Coons fill;
and how hard wireframes surface.

Run: ``python benchmarks/bench_surface.py [--templates N] [--hard N]``. For every template:
read the wireframe STEP, skeletons (Algorithm 1, per region), control nets + DTW, OCCT faces,
sewing, shell checks, STEP write. Quality per region (faces, inner G1 where the sides are smooth,
G1 across ribs at side corners, min scaled Jacobian) and across region seams (G0, G1), compared
with one ``GeomFill_BSplineCurves`` Coons patch per region bounded by the same four sides.

Then ``--hard N`` random hard wireframes (:mod:`carbody.surface.stress`, seeds 0..N-1, the four
kinds in turn): how many surface with the paper's layout in every region, how many need the
layout by arc length in some region (:mod:`carbody.surface.arc_layout`; before it, those bodies
failed), how many fail (a SurfaceError), per kind and per region, and the time per body.
"""
from __future__ import annotations

import argparse
import statistics
from collections import Counter
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def coons_surfaces(control_points: np.ndarray) -> dict[str, object]:
    """One Coons patch (OCCT GeomFill, CoonsStyle) per region, bounded by its four sides."""
    from OCP.Geom import Geom_BezierCurve
    from OCP.GeomConvert import GeomConvert, GeomConvert_CompCurveToBSplineCurve
    from OCP.GeomFill import GeomFill_BSplineCurves, GeomFill_FillingStyle
    from OCP.gp import gp_Pnt
    from OCP.TColgp import TColgp_Array1OfPnt

    from carbody.surface.regions import region_outlines

    def bspline(pieces):
        comp = None
        for poles in pieces:
            arr = TColgp_Array1OfPnt(1, 4)
            for i, p in enumerate(poles):
                arr.SetValue(i + 1, gp_Pnt(*map(float, p)))
            c = GeomConvert.CurveToBSplineCurve_s(Geom_BezierCurve(arr))
            if comp is None:
                comp = GeomConvert_CompCurveToBSplineCurve(c)
            else:
                comp.Add(c, 1e-6)
        return comp.BSplineCurve()

    out = {}
    for o in region_outlines(control_points):
        # GeomFill wants the four curves end to end round the loop
        c1 = bspline([o.begin])
        c2 = bspline(list(o.side_a.poles))
        c3 = bspline([o.end[::-1]])
        c4 = bspline([p[::-1] for p in o.side_b.poles[::-1]])
        fill = GeomFill_BSplineCurves(c1, c2, c3, c4, GeomFill_FillingStyle.GeomFill_CoonsStyle)
        out[o.name] = fill.Surface()
    return out


def seam_g1(surfaces_of: dict[str, list], control_points: np.ndarray, n: int = 9) -> dict[str, float]:
    """Max normal angle (deg) along each wireframe curve shared by two regions (or a region and
    its mirror), normals by projecting curve points onto each region's surfaces."""
    from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
    from OCP.GeomLProp import GeomLProp_SLProps
    from OCP.gp import gp_Pnt

    from carbody.topology import load_topology

    topo = load_topology()
    users: dict[int, list[str]] = {}
    for r in topo.regions:
        for ci, _ in r.loop:
            users.setdefault(ci, []).append(r.name)
    t = np.linspace(0.05, 0.95, n)[:, None]
    basis = np.hstack([(1 - t) ** 3, 3 * (1 - t) ** 2 * t, 3 * (1 - t) * t**2, t**3])

    def normal(region, p):
        best = None
        for s in surfaces_of[region]:
            proj = GeomAPI_ProjectPointOnSurf(gp_Pnt(*map(float, p)), s)
            if proj.NbPoints() and (best is None or proj.LowerDistance() < best[0]):
                u, v = proj.LowerDistanceParameters()
                best = (proj.LowerDistance(), s, u, v)
        _, s, u, v = best
        props = GeomLProp_SLProps(s, u, v, 1, 1e-9)
        d = props.Normal()
        return np.array([d.X(), d.Y(), d.Z()])

    out = {}
    for c in topo.curves:
        regions = users.get(c.index, [])
        sym = c.start in topo.symmetry_junctions and c.end in topo.symmetry_junctions
        if not (len(regions) == 2 or (sym and len(regions) == 1)):
            continue
        pts = basis @ control_points[4 * c.index:4 * c.index + 4]
        worst = 0.0
        for p in pts:
            n1 = normal(regions[0], p)
            n2 = normal(regions[1], p) if len(regions) == 2 else n1 * [-1.0, 1.0, 1.0]
            worst = max(worst, float(np.degrees(np.arccos(np.clip(abs(n1 @ n2), -1, 1)))))
        key = "|".join(sorted(regions)) if len(regions) == 2 else f"{regions[0]}|mirror"
        out[key] = max(out.get(key, 0.0), worst)
    return out


#: What the paper's layout failing on a region did before the layout by arc length, by the start
#: of its note (``report["regions"][name]["layout_note"]`` after the region's name).
BEFORE = (("its boundary projected onto its best-fit plane crosses itself", "SurfaceError: crosses itself"),
          ("its boundary projected onto its best-fit plane encloses no area", "SurfaceError: degenerate"),
          ("its junction ribs cross", "AssertionError: junction ribs cross"),
          ("its ribs cross", "AssertionError: junction ribs cross"),
          ("no rib ends where", "AssertionError: sub-arc spans a junction"))


def arc_layout_on_templates(wireframes: list) -> None:
    """Print, per region over the templates, the paper's layout against the layout by arc length
    forced on every region: what a region loses where it has to be laid out by arc length."""
    from carbody.surface.arc_layout import arc_length_net
    from carbody.surface.body import MIN_GAP_SPACINGS, region_layout, wheelbase_of
    from carbody.surface.quality import region_report
    from carbody.surface.regions import region_outlines
    from carbody.tolerances import NORMALISED_WHEELBASE, SKELETON_SPACING_NORM

    rows: dict[str, list] = {}
    for cp in wireframes:
        wb = wheelbase_of(cp)
        for o in region_outlines(cp):
            paper, _ = region_layout(o, wb)
            arc = arc_length_net(o, MIN_GAP_SPACINGS * SKELETON_SPACING_NORM * wb / NORMALISED_WHEELBASE)
            rows.setdefault(o.name, []).append([region_report(n.faces, n.side_turn_deg) for n in (paper, arc)])
    print("\nThe layout by arc length forced on every template region, against the paper's (faces "
          "median; inner G1 max; smallest scaled Jacobian of the surfaces, as above):\n")
    print("| region | faces, paper | faces, arc | inner G1 °, paper | inner G1 °, arc | Jacobian, paper "
          "| Jacobian, arc |\n|---|---|---|---|---|---|---|")
    for name, rs in rows.items():
        p, a = [r[0] for r in rs], [r[1] for r in rs]
        print(f"| {name} | {statistics.median(r['faces'] for r in p):.0f} | {statistics.median(r['faces'] for r in a):.0f} | "
              f"{max(r['inner_g1_deg'] for r in p):.2f} | {max(r['inner_g1_deg'] for r in a):.2f} | "
              f"{min(r['min_surface_jacobian'] for r in p):.2f} | {min(r['min_surface_jacobian'] for r in a):.2f} |")


def hard_wireframes_table(n: int) -> None:
    """Print the hard-wireframe tables (see module docstring) for seeds 0..n-1."""
    import os
    import re
    from collections import defaultdict

    from carbody.errors import SurfaceError
    from carbody.library import load_library
    from carbody.surface import build_body
    from carbody.surface.stress import KINDS, stress_wireframe
    from carbody.topology import load_topology

    library = load_library()
    stress_wireframe(library, 1)  # the displacement field's basis, outside the timings
    outcome: dict[str, Counter] = defaultdict(Counter)
    times: dict[str, list[float]] = defaultdict(list)
    regions: dict[str, Counter] = defaultdict(Counter)
    before: Counter = Counter()
    failures: Counter = Counter()
    for seed in range(n):
        wf = stress_wireframe(library, seed)
        kind = wf.name.split()[0]
        t = time.perf_counter()
        try:
            body = build_body(wf)
        except SurfaceError as exc:
            result = "failed"
            failures[re.sub(r"curves? [\w, ]+|junctions .*", "…", str(exc).split(": ", 1)[-1])] += 1
        else:
            notes = {name: r["layout_note"].split(": ", 1)[-1] for name, r in body.report["regions"].items()
                     if r["layout"] != "skeleton"}
            result = "arc_length" if notes else "paper"
            for name, note in notes.items():
                was = next((b for start, b in BEFORE if note.startswith(start)), note)
                regions[name][was] += 1
            if notes:
                # the body failed on the first region (topology order) the paper's layout could not do
                first = next(name for name in (r.name for r in load_topology().regions) if name in notes)
                before[next((b for start, b in BEFORE if notes[first].startswith(start)), notes[first])] += 1
        outcome[kind][result] += 1
        times[result].append(time.perf_counter() - t)
        print(f"hard {seed:4d} {kind:12s} {result:10s} {times[result][-1]:5.2f} s", file=sys.stderr)

    cols = ("paper", "arc_length", "failed")
    print(f"\n### Hard wireframes ({n}, `--hard {n}`)\n")
    print(f"{os.cpu_count()}-core machine (2 cores, shared with other jobs; load average "
          f"{os.getloadavg()[0]:.1f} at the end). Seeds 0..{n - 1} of `carbody.surface.stress`, the kinds in "
          f"turn. *paper*: every region laid out by the paper's skeleton (the only bodies that "
          f"surfaced before the layout by arc length; their faces are unchanged); *arc length*: some "
          f"region laid out by arc length (each of these failed before); *failed*: a SurfaceError.\n")
    print("| kind | wireframes | paper | arc length | failed |\n|---|---|---|---|---|")
    for kind in KINDS:
        c = outcome[kind]
        print(f"| {kind} | {sum(c.values())} | " + " | ".join(str(c[k]) for k in cols) + " |")
    total = Counter()
    for c in outcome.values():
        total.update(c)
    print(f"| **all** | **{n}** | " + " | ".join(f"**{total[k]}**" for k in cols) + " |")
    print("\nSeconds per body (build_body with the shell checks, warm process):\n")
    print("| bodies | count | median | max |\n|---|---|---|---|")
    for k in cols:
        if times[k]:
            print(f"| {k.replace('_', ' ')} | {len(times[k])} | {statistics.median(times[k]):.2f} | {max(times[k]):.2f} |")
    print("\nBefore, each *arc length* body failed on its first such region (topology order):\n")
    print("| failure before | bodies |\n|---|---|")
    for k, v in before.most_common():
        print(f"| {k} | {v} |")
    print("\nRegions laid out by arc length, by what the paper's layout did with them:\n")
    kinds_before = sorted({b for c in regions.values() for b in c})
    print("| region | " + " | ".join(kinds_before) + " | total |\n|---|" + "---|" * (len(kinds_before) + 1))
    for r in load_topology().regions:
        c = regions.get(r.name, Counter())
        print(f"| {r.name} | " + " | ".join(str(c[k]) for k in kinds_before) + f" | {sum(c.values())} |")
    if failures:
        print("\nFailures (SurfaceError, curve names elided):\n")
        print("| error | bodies |\n|---|---|")
        for k, v in failures.most_common():
            print(f"| {k} | {v} |")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--templates", type=int, default=0, help="only the first N templates (0 = all)")
    ap.add_argument("--hard", type=int, default=60, help="random hard wireframes to surface (0 = none)")
    args = ap.parse_args()

    from OCP.BRep import BRep_Tool

    from carbody.occ.step_body import write_body_step  # noqa: F401  (import cost outside timings)
    from carbody.surface import build_body
    from carbody.surface.body import region_skeleton, wheelbase_of, write_body
    from carbody.surface.regions import region_outlines
    from carbody.templates import load_manifest, templates_dir
    from carbody.wireframe import read_wireframe

    rows = load_manifest()
    if args.templates:
        rows = rows[: args.templates]
    out_dir = Path("/tmp/carbody_bench_surface")
    out_dir.mkdir(exist_ok=True)
    read_wireframe(templates_dir() / rows[0]["file"])  # warm OCP imports

    totals, stages, skel_max, quality, seams_ours, seams_coons, coons_t = [], {}, [], {}, [], [], []
    for row in rows:
        t0 = time.perf_counter()
        wf = read_wireframe(templates_dir() / row["file"])
        t1 = time.perf_counter()
        body = build_body(wf)
        t2 = time.perf_counter()
        write_body(out_dir / row["file"], body)
        t3 = time.perf_counter()
        tim = dict(body.report["timings_s"], read_s=t1 - t0, write_step_s=t3 - t2)
        totals.append(t3 - t0)
        for k, v in tim.items():
            stages.setdefault(k, []).append(v)
        wb = wheelbase_of(wf.control_points)
        per_region = []
        for o in region_outlines(wf.control_points):
            t = time.perf_counter()
            region_skeleton(o, wb)
            per_region.append(time.perf_counter() - t)
        skel_max.append(max(per_region))
        for name, r in body.report["regions"].items():
            quality.setdefault(name, []).append(r)

        # seams: ours vs one Coons patch per region
        ours: dict[str, list] = {}
        for (region, face), patch in zip(body.faces, body.patches):
            if not patch.mirror:
                ours.setdefault(region, []).append(BRep_Tool.Surface_s(face))
        seams_ours.append(seam_g1(ours, wf.control_points))
        t = time.perf_counter()
        coons = coons_surfaces(wf.control_points)
        coons_t.append(time.perf_counter() - t)
        seams_coons.append(seam_g1({k: [v] for k, v in coons.items()}, wf.control_points))
        print(f"{row['name']:32s} total {t3 - t0:5.2f} s  faces {body.report['shell']['faces']}  "
              f"valid {body.report['shell']['valid']}", file=sys.stderr)

    import os

    load = os.getloadavg()[0]
    print("\n## Surfaces (`benchmarks/bench_surface.py`)\n")
    print(f"{len(rows)} templates; 2-core machine, load average {load:.1f} during the run "
          f"(other jobs share the cores).\n")
    print("Wireframe STEP -> body STEP, seconds per body (warm process):\n")
    print("| stage | median | max |\n|---|---|---|")
    order = ["read_s", "skeleton_s", "control_nets_s", "faces_s", "sewing_s", "checks_s", "write_step_s"]
    for k in order:
        v = stages[k]
        print(f"| {k[:-2]} | {statistics.median(v):.3f} | {max(v):.3f} |")
    print(f"| **total** | **{statistics.median(totals):.3f}** | **{max(totals):.3f}** |")
    print(f"\nSkeleton, slowest region per body: median {statistics.median(skel_max):.3f} s, "
          f"max {max(skel_max):.3f} s (goal ≤ 0.1 s). Total goal ≤ 3 s.\n")
    print("Per region, over all templates (faces median; inner G1 = max normal angle across ribs where "
          "both sides are smooth; corner G1 = across ribs ending at a corner of a side; Jacobian = "
          "smallest scaled Jacobian of the control nets' quads, and of the surfaces themselves on a "
          "9 x 9 grid against each face's mean normal):\n")
    print("| region | faces | inner G1 ° max | corner ribs | corner G1 ° max | min scaled Jacobian, net "
          "| min scaled Jacobian, surface |")
    print("|---|---|---|---|---|---|---|")
    for name, rs in quality.items():
        print(f"| {name} | {statistics.median([r['faces'] for r in rs]):.0f} | "
              f"{max(r['inner_g1_deg'] for r in rs):.3f} | {max(r['corner_ribs'] for r in rs)} | "
              f"{max(r['corner_g1_deg'] for r in rs):.1f} | {min(r['min_scaled_jacobian'] for r in rs):.2f} | "
              f"{min(r['min_surface_jacobian'] for r in rs):.2f} |")
    print("\nAcross region seams (G1 normal angle along shared wireframe curves, degrees; G0 is 0 for "
          "both since both interpolate the wireframe):\n")
    print("| seam | ours median | ours max | Coons median | Coons max |\n|---|---|---|---|---|")
    keys = sorted(set().union(*seams_ours))
    for k in keys:
        a = [s[k] for s in seams_ours if k in s]
        b = [s[k] for s in seams_coons if k in s]
        print(f"| {k} | {statistics.median(a):.1f} | {max(a):.1f} | {statistics.median(b):.1f} | {max(b):.1f} |")
    all_a = [v for s in seams_ours for v in s.values()]
    all_b = [v for s in seams_coons for v in s.values()]
    print(f"| **all seams** | **{statistics.median(all_a):.1f}** | **{max(all_a):.1f}** | "
          f"**{statistics.median(all_b):.1f}** | **{max(all_b):.1f}** |")
    print(f"\nCoons fill of the 13 regions: {statistics.median(coons_t):.3f} s median (surfaces only, "
          f"no faces or sewing).")
    layouts = Counter(r["layout"] for rs in quality.values() for r in rs)
    print(f"\nRegion layouts over the templates: {dict(layouts)}.")
    arc_layout_on_templates([read_wireframe(templates_dir() / row["file"]).control_points for row in rows])
    if args.hard:
        hard_wireframes_table(args.hard)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
