"""``carbody demo``: the main job on the example that ships in the repository.

Until fitting lands this writes every template's STEP round trip and its labelled four-view
drawing into the output folder.
"""
from __future__ import annotations

import argparse
from pathlib import Path


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="run the main job on the shipped example")
    p.add_argument("--out", type=Path, default=Path("out"), help="output folder (default: out/)")
    p.set_defaults(func=_demo)


def _demo(args) -> int:
    from carbody.errors import CarbodyError
    from carbody.templates import load_templates, measure_template
    from carbody.templates.drawing import draw_four_views
    from carbody.wireframe import read_wireframe, write_wireframe

    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CarbodyError(f"{args.out}: cannot create the output folder ({exc.strerror})") from None
    for row, wf in load_templates():
        stem = Path(row["file"]).stem
        step = write_wireframe(args.out / f"{stem}.step", wf, both_halves=True)
        back = read_wireframe(step)
        drift = abs(back.control_points - wf.control_points).max()
        draw_four_views(back.control_points, args.out / f"{stem}.png", wf.name)
        m = measure_template(row, back)
        print(f"{wf.name:32s} {step}  round trip {drift:.1e} mm  "
              f"L {m['length_mm']:.0f} W {m['width_mm']:.0f} H {m['height_mm']:.0f} WB {m['wheelbase_mm']:.0f}")
    print(f"wrote STEP files and four-view drawings to {args.out.resolve()}")
    return 0
