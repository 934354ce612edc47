"""``carbody demo``: the main job on the example that ships in the repository.

Runs the whole pipeline on ``examples/car.png`` and its keypoints, with the view told by the
shipped classifier, and compares the result with the example's true wireframe.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from carbody.shipped import EXAMPLES


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="run the whole pipeline on the shipped example photo")
    p.add_argument("--out", type=Path, default=Path("out"), help="output folder (default: out/)")
    p.add_argument("--view", type=float, default=None, help="give the view instead of asking the classifier")
    p.set_defaults(func=_demo)


def _demo(args) -> int:
    from carbody.cli import build_parser
    from carbody.reconstruct_cli import run_reconstruct

    argv = ["reconstruct", str(EXAMPLES / "car.png"), "--keypoints", str(EXAMPLES / "car_keypoints.json"),
            "--truth", str(EXAMPLES / "car_truth.step"), "--name", "carbody example crossover",
            "--out", str(args.out)] + ([] if args.view is None else ["--view", str(args.view)]) \
        + (["--quiet"] if args.quiet else [])
    return run_reconstruct(build_parser().parse_args(argv))  # reconstruct's own defaults
