"""``carbody reconstruct``: photo + keypoints -> wireframe, body, assembly, pictures, report."""
from __future__ import annotations

import argparse
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
                   help="the car's wheelbase in mm (default: from the fitted car's proportions); "
                        "told, the fit also knows the car's width and height in mm")
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


def run_reconstruct(args: argparse.Namespace, out=sys.stdout) -> int:
    from carbody.camera import read_view
    from carbody.fit.cli import library_without, parse_distance
    from carbody.outputs import output_folder
    from carbody.pipeline import check_output_dir

    distance = parse_distance(args.distance)
    view = None if args.view is None else read_view(args.view)
    library = library_without(args.exclude_template) if args.exclude_template else None
    # The folder is made now, so that it can be checked before the work; a run that fails
    # removes it again if it is still empty (never the files another run has put there since).
    with output_folder(args.out):
        check_output_dir(args.out, inputs={"the photo": args.image, "the keypoint file": args.keypoints,
                                           "the ground truth": args.truth})
        return _reconstruct_into(args, view, distance, library, out)


def _reconstruct_into(args: argparse.Namespace, view, distance, library, out) -> int:
    from carbody.errors import CarbodyError
    from carbody.fit.cli import load_truth
    from carbody.pipeline import STAGES, reconstruct
    from carbody.progress import progress

    truth = load_truth(args.truth) if args.truth else None

    def on_stage(label: str) -> None:
        bar.start(label)
        if args.progress:  # a line per stage for a program reading stderr (the FreeCAD workbench)
            k = (STAGES + ("write",)).index(label) + 1
            print(f"carbody: stage {label} ({k}/{len(STAGES) + 1})", file=sys.stderr, flush=True)

    with progress((*STAGES, "write"), args.quiet) as bar:
        try:
            result = reconstruct(args.image, args.keypoints, view, args.wheelbase, name=args.name,
                                 elevation_deg=args.elevation, camera_distance_mm=distance, library=library,
                                 principal_point=args.principal_point, focal_35mm=args.focal_35mm,
                                 reject_outliers=not args.keep_marks, view_prior_weight=args.view_weight,
                                 outline=args.outline, wheels=args.wheels, force=args.force, on_stage=on_stage)
        except CarbodyError as exc:
            partial = getattr(exc, "partial", None)
            if partial is None:
                raise
            # failed after the fit: what shows why is written, beside the one line
            on_stage("write")
            written = partial.write_failed(args.out, truth)
            raise type(exc)(f"{exc}; wrote {', '.join(p.name for p in written)} to {args.out}") from None
        on_stage("write")
        paths = result.write(args.out, truth)
    print((args.out / "summary.txt").read_text(), end="", file=out)
    print(f"wrote {', '.join(sorted(p.name for p in paths.values()))} to {args.out.resolve()}", file=out)
    return 0
