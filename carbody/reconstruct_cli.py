"""``carbody reconstruct``: photo + keypoints -> wireframe, body, assembly, pictures, report."""
from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path


def add_parsers(sub: argparse._SubParsersAction) -> None:
    from carbody.fit.cli import add_camera_arguments, add_marks_argument

    p = sub.add_parser("reconstruct", help="photo + keypoints -> wireframe and body STEP, pictures, report",
                       description="Run view (unless --view is given) -> fit -> surfaces and write "
                                   "wireframe.step, body.step, car.step (assembly), overlay.png, body.png, "
                                   "report.json and summary.txt into OUT_DIR.")
    p.add_argument("image", type=Path, help="the car photo (PNG, JPEG, ...)")
    p.add_argument("--keypoints", "-k", required=True, type=Path,
                   help="keypoints marked on the photo: the project's JSON, COCO keypoints or labelme")
    p.add_argument("--view", default=None,
                   help="view azimuth in degrees (0 front, 90 left side, 180 rear, 270 right side) "
                        "or a name ('front 30', 'rear 30 right'): a prior on the search over every view; "
                        "default: the shipped view classifier's probabilities")
    p.add_argument("--wheelbase", type=float, default=None,
                   help="the car's wheelbase in mm (default: fitted); told, the fit also knows "
                        "the car's width and height in mm")
    p.add_argument("--elevation", type=float, default=0.0,
                   help="camera elevation told, degrees (default 0: a prior of the search)")
    add_camera_arguments(p)
    add_marks_argument(p)
    p.add_argument("--exclude-template", action="append", default=[], metavar="NAME",
                   help="leave this template (and its expansions) out of the library; repeatable "
                        "(how the tool does on a car it has never seen)")
    p.add_argument("--truth", default=None, help="ground truth wireframe STEP or template name: adds 3D errors")
    p.add_argument("--name", default=None, help="the car's name in the STEP files (default: photo file stem)")
    p.add_argument("-o", "--out", required=True, type=Path, help="output folder")
    p.add_argument("--progress", action="store_true",
                   help="also print a line 'carbody: stage NAME (K/N)' on stderr as each stage starts "
                        "(for a program running this one: the bar shows only at a terminal)")
    p.set_defaults(func=run_reconstruct)


def load_truth(spec: str):
    """A ground-truth wireframe from a STEP file or a template name."""
    from carbody.templates import load_template
    from carbody.wireframe import read_wireframe

    return read_wireframe(spec) if Path(spec).suffix.lower() in (".step", ".stp") else load_template(spec)


def run_reconstruct(args: argparse.Namespace, out=sys.stdout) -> int:
    from carbody.camera import read_view
    from carbody.fit.cli import parse_distance
    from carbody.pipeline import prepare_output_dir

    from carbody.fit.cli import library_without

    distance = parse_distance(args.distance)
    view = None if args.view is None else read_view(args.view)
    library = library_without(args.exclude_template) if args.exclude_template else None
    created = not Path(args.out).exists()
    prepare_output_dir(args.out)  # fail before the work, not after
    try:
        return _reconstruct_into(args, view, distance, library, out)
    except BaseException:
        if created:  # a folder made for outputs that never came is not left behind
            shutil.rmtree(args.out, ignore_errors=True)
        raise


def _reconstruct_into(args: argparse.Namespace, view, distance, library, out) -> int:
    from tqdm import tqdm

    from carbody.pipeline import STAGES, reconstruct

    truth = load_truth(args.truth) if args.truth else None
    # The bar is for a person at a terminal: none in a log or a pipe (tqdm's ``disable=None``).
    with tqdm(total=len(STAGES) + 1, desc="carbody", unit="stage", file=sys.stderr, disable=None,
              bar_format="{desc}: {n_fmt}/{total_fmt} {bar} {elapsed}") as bar:
        def on_stage(label: str) -> None:
            if bar.n or label != STAGES[0]:
                bar.update(1)
            bar.set_description(label)
            if args.progress:
                say_stage(label)

        def say_stage(label: str) -> None:
            k = (STAGES + ("write",)).index(label) + 1
            print(f"carbody: stage {label} ({k}/{len(STAGES) + 1})", file=sys.stderr, flush=True)

        result = reconstruct(args.image, args.keypoints, view, args.wheelbase, name=args.name,
                             elevation_deg=args.elevation, camera_distance_mm=distance, library=library,
                             principal_point=args.principal_point, focal_35mm=args.focal_35mm,
                             reject_outliers=not args.keep_marks, view_prior_weight=args.view_weight,
                             outline=args.outline,
                             on_stage=on_stage)
        bar.update(1)
        bar.set_description("write")
        if args.progress:
            say_stage("write")
        paths = result.write(args.out, truth)
        bar.update(1)
    print((args.out / "summary.txt").read_text(), end="", file=out)
    print(f"wrote {', '.join(sorted(p.name for p in paths.values()))} to {args.out.resolve()}", file=out)
    return 0
