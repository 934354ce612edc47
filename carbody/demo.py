"""``carbody demo``: the main job on the example that ships in the repository.

Runs the whole pipeline on ``examples/car.png`` and its keypoints, with the view told by the
shipped classifier, and compares the result with the example's true wireframe.
"""
from __future__ import annotations

import argparse
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="run the whole pipeline on the shipped example photo")
    p.add_argument("--out", type=Path, default=Path("out"), help="output folder (default: out/)")
    p.add_argument("--view", type=float, default=None, help="give the view instead of asking the classifier")
    p.set_defaults(func=_demo)


def _demo(args) -> int:
    from carbody.reconstruct_cli import run_reconstruct

    ns = argparse.Namespace(image=EXAMPLES / "car.png", keypoints=EXAMPLES / "car_keypoints.json",
                            view=args.view, wheelbase=None, truth=str(EXAMPLES / "car_truth.step"),
                            name="carbody example crossover", out=args.out)
    return run_reconstruct(ns)
