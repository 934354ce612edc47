"""``carbody surface`` and ``carbody skeleton``: a thin layer over :mod:`carbody.surface`."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("surface", help="surface a wireframe: Bezier faces sewn into one shell (STEP)",
                       description="Wireframe STEP -> 13 regions -> skeletons -> control nets -> Bezier "
                                   "faces of both halves sewn into one shell, written as AP214 STEP (mm) "
                                   "with faces named and coloured by region.")
    p.add_argument("wireframe", type=Path, help="wireframe STEP (a template, a fitted car, or one saved by "
                   "FreeCAD, CadQuery or build123d with the curves named) or wireframe JSON")
    p.add_argument("-o", "--output", type=Path, required=True, help="body STEP to write")
    p.add_argument("--report", type=Path, metavar="JSON", help="write the quality report here (with every "
                   "face's name, region, colour and centre)")
    p.add_argument("--refuse-folds", action="store_true", help="write nothing and exit 2 when a region folds "
                   "(default: write the body and say which regions fold)")
    p.add_argument("--png", type=Path, metavar="FILE", help="render the shaded body from three views")
    p.set_defaults(func=_surface)

    p = sub.add_parser("skeleton", help="one region's skeleton: boundary, optimal pairs, skeleton line",
                       description="Run the Skeleton Generation Algorithm (paper Algorithm 1) on one region.")
    p.add_argument("wireframe", type=Path, help="wireframe STEP")
    p.add_argument("--region", required=True, help="region name (see carbody/data/topology.json)")
    p.add_argument("--png", type=Path, metavar="FILE", help="draw boundary, pairs and skeleton (Fig. 17-18)")
    p.add_argument("--json", action="store_true", help="print pairs and skeleton as JSON")
    p.set_defaults(func=_skeleton)


def read_surface_wireframe(path: Path):
    """Read a wireframe; a loop that does not close is reported naming the region.

    ``read_wireframe`` refuses curves that miss their junctions, naming curves; for surfacing
    the user needs to know which region cannot be closed, so the curves are read again as they
    are and the first region whose loop is open is named.
    """
    from carbody.errors import TemplateError
    from carbody.wireframe import read_wireframe

    try:
        return read_wireframe(path)
    except TemplateError as exc:
        if "do not meet at junction" not in str(exc):
            raise
        import numpy as np

        from carbody.surface.regions import region_outline
        from carbody.topology import load_topology
        from carbody.wireframe import read_named_curves

        topo = load_topology()
        _, curves = read_named_curves(path)
        by_name = {c.name: c.poles for c in curves if len(c.poles) == 4}
        if not all(c.name in by_name for c in topo.curves):
            raise
        cp = np.concatenate([by_name[c.name] for c in topo.curves])
        for region in topo.regions:
            region_outline(cp, region, 1.0, topo)  # raises SurfaceError naming the region
        raise


def _surface(args) -> int:
    import time

    from carbody.outputs import JSON, PICTURE, STEP, check_distinct, check_not_inputs, check_output_file, staged
    from carbody.progress import progress
    from carbody.surface.body import build_body, write_body

    check_output_file(args.output, STEP)  # refuse before any work, write nothing
    if args.report:
        check_output_file(args.report, JSON)
    if args.png:
        check_output_file(args.png, PICTURE)
    outputs = {"--output": args.output, "--report": args.report, "--png": args.png}
    check_distinct(outputs)
    check_not_inputs(outputs, {"the wireframe": args.wireframe})
    with progress(("read", "surfaces", "write"), args.quiet) as bar:
        bar.start("read")
        t0 = time.perf_counter()
        wf = read_surface_wireframe(args.wireframe)
        bar.start("surfaces")
        t1 = time.perf_counter()
        body = build_body(wf)
        folds = body.report["folds"]
        if folds and args.refuse_folds:
            from carbody.errors import FoldError

            more = len(folds) - 1
            raise FoldError(folds[0] + (f"; {more} more region{'s fold' if more > 1 else ' folds'} too" if more else ""))
        bar.start("write")
        t2 = time.perf_counter()
        with staged(p for p in outputs.values() if p is not None) as at:
            write_body(at(args.output), body)
            t3 = time.perf_counter()
            body.report["timings_s"].update({"read_s": t1 - t0, "build_s": t2 - t1, "write_step_s": t3 - t2})
            if args.report:
                from carbody.parts_cli import body_faces

                text = json.dumps({**body.report, "faces": body_faces(body)}, indent=1, default=float)
                at(args.report).write_text(text)
            if args.png:
                from carbody.surface.render import render_body

                render_body(body, at(args.png))
    shell = body.report.get("shell", {})
    print(f"wrote {args.output}: {shell.get('faces', len(body.faces))} faces, one shell, "
          f"valid={shell.get('valid')}, free loops={shell.get('free_closed_loops')}", file=sys.stderr)
    for line in folds:
        print(f"carbody surface: warning: {line}", file=sys.stderr)
    by_arc = [n for n, r in body.report["regions"].items() if r["layout"] != "skeleton"]
    if by_arc:
        print(f"laid out by arc length (their outlines fold in their best-fit planes, or their ribs "
              f"cross): {', '.join(by_arc)}", file=sys.stderr)
    return 0


def _skeleton(args) -> int:
    from carbody.errors import SurfaceError
    from carbody.surface.body import region_skeleton, wheelbase_of
    from carbody.surface.regions import outward_sign, region_outline
    from carbody.topology import load_topology

    topo = load_topology()
    names = [r.name for r in topo.regions]
    if args.region not in names:
        raise SurfaceError(f"unknown region {args.region!r} (known: {', '.join(names)})")
    if args.png:
        from carbody.outputs import PICTURE, check_not_inputs, check_output_file

        check_output_file(args.png, PICTURE)
        check_not_inputs({"--png": args.png}, {"the wireframe": args.wireframe})
    wf = read_surface_wireframe(args.wireframe)
    cp = wf.control_points
    outline = region_outline(cp, topo.region(args.region), outward_sign(cp, topo), topo)
    sk = region_skeleton(outline, wheelbase_of(cp, topo))
    if args.png:
        from carbody.occ.step_curves import atomic_write
        from carbody.surface.drawing import draw_skeleton

        atomic_write(args.png, lambda tmp: draw_skeleton(sk, tmp))
        print(f"wrote {args.png}", file=sys.stderr)
    if args.json or not args.png:
        print(json.dumps({
            "region": args.region,
            "samples": len(sk.samples.points2d),
            "pairs": [{"i": p.i, "j": p.j, "ijvalue": p.value, "arearatio": p.arearatio, "depth": p.depth}
                      for p in sk.pairs],
            "skeleton": sk.line.round(4).tolist(),
        }))
    return 0
