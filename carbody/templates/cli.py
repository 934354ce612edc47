"""``carbody templates ...``: list, show, build and check the template library."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("templates", help="the template cars (list, show, build, check)",
                       description="The template library: real cars as STEP wireframes.")
    tsub = p.add_subparsers(dest="templates_command", metavar="ACTION", required=True)

    q = tsub.add_parser("list", help="list the templates")
    q.add_argument("--json", action="store_true", help="print a JSON list")
    q.add_argument("--dir", type=Path, help="template folder (default: the shipped templates_step/)")
    q.set_defaults(func=_list)

    q = tsub.add_parser("show", help="one template's control points and keypoints, or its drawing")
    q.add_argument("name", help="car name or file stem, e.g. 'Toyota Camry XV70' or toyota_camry_xv70")
    q.add_argument("--json", action="store_true", help="print {name, control_points, keypoints} as JSON")
    q.add_argument("--png", type=Path, metavar="FILE", help="write the four views with keypoints labelled")
    q.add_argument("--dir", type=Path, help="template folder")
    q.set_defaults(func=_show)

    q = tsub.add_parser("build", help="build the template STEP files from a design table")
    q.add_argument("--design-table", type=Path, help="design table JSON (default: the shipped one)")
    q.add_argument("--out", type=Path, required=True,
                   help="output folder (the repository's library: templates_step/; an installed "
                        "package's own is not written: build into a folder of yours and point "
                        "$CARBODY_TEMPLATES_DIR at it)")
    q.set_defaults(func=_build)

    q = tsub.add_parser("check", help="measure every template against its manifest (1 %% tolerance)")
    q.add_argument("--dir", type=Path, help="template folder")
    q.set_defaults(func=_check)


def _list(args) -> int:
    from carbody.templates import load_manifest

    rows = [{"name": r["name"], "class": r["class"], "length_mm": r["length_mm"], "width_mm": r["width_mm"],
             "height_mm": r["height_mm"], "wheelbase_mm": r["wheelbase_mm"], "file": r["file"]}
            for r in load_manifest(args.dir)]
    if args.json:
        print(json.dumps(rows, indent=1))
    else:
        print(f"{'name':32s} {'class':11s} {'length':>7s} {'width':>6s} {'height':>6s} {'wheelbase':>9s}")
        for r in rows:
            print(f"{r['name']:32s} {r['class']:11s} {r['length_mm']:7.0f} {r['width_mm']:6.0f} "
                  f"{r['height_mm']:6.0f} {r['wheelbase_mm']:9.0f}")
    return 0


def _show(args) -> int:
    from carbody.templates import load_template

    if args.png:
        from carbody.outputs import PICTURE, check_output_file

        check_output_file(args.png, PICTURE)
    wf = load_template(args.name, args.dir)
    if args.png:
        from carbody.templates.drawing import draw_four_views

        draw_four_views(wf.control_points, args.png, wf.name)
        print(f"wrote {args.png}", file=sys.stderr)
    if args.json or not args.png:
        print(json.dumps({"name": wf.name, "control_points": wf.control_points.round(6).tolist(),
                          "keypoints": wf.keypoints()}))
    return 0


def _build(args) -> int:
    from carbody.templates import build_templates

    rows = build_templates(args.out, args.design_table, quiet=args.quiet)
    print(f"wrote {len(rows)} templates and manifest.json to {args.out}")
    return 0


def _check(args) -> int:
    from carbody.errors import TemplateError
    from carbody.templates import load_templates, measure_template
    from carbody.tolerances import DIMENSION_REL_TOL

    worst = 0.0
    for row, wf in load_templates(args.dir):
        m = measure_template(row, wf)
        errs = {k: m[k] / row[k] - 1 for k in m}
        worst = max(worst, *map(abs, errs.values()))
        print(f"{row['name']:32s} " + " ".join(f"{k[:-3]} {v:+.3%}" for k, v in errs.items()))
    if worst > DIMENSION_REL_TOL:
        raise TemplateError(f"a template is off its manifest by {worst:.2%} (> {DIMENSION_REL_TOL:.0%})")
    return 0
