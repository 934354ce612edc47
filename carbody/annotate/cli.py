"""``carbody annotate``: mark a photo's keypoints on a local page that fits the car as you click."""
from __future__ import annotations

import argparse
from pathlib import Path


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "annotate", help="mark a photo's keypoints on a local web page that fits the car live",
        description="Open a page (127.0.0.1 only) showing the photo: it asks for one keypoint at a "
                    "time, shows where it is on a reference car, and from the fifth mark on refits "
                    "the car on every click and draws the wireframe and the predicted place of every "
                    "keypoint not marked yet (accept with Enter, or drag into place). S saves the "
                    "marks as the project's JSON (COCO too on request); Reconstruct runs the whole "
                    "job. See docs/annotate.md.")
    p.add_argument("image", type=Path, help="the car photo (PNG, JPEG, ...)")
    p.add_argument("-k", "--keypoints", type=Path, default=None,
                   help="marks to start from (the project's JSON, COCO or labelme): shown as placed "
                        "and saved unchanged unless moved")
    p.add_argument("-o", "--out", type=Path, default=None,
                   help="where Save writes the marks, .json (default: the -k file, else "
                        "IMAGE_keypoints.json beside the photo)")
    p.add_argument("--coco", action="store_true", help="Save also writes COCO keypoints (OUT.coco.json)")
    p.add_argument("--view", default=None,
                   help="the view to start from (degrees or a name: 'front 30'); default the view "
                        "classifier's guess")
    p.add_argument("--port", type=int, default=0, help="port to listen on (default: any free one)")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser (print the URL)")
    p.set_defaults(func=run_annotate)


def run_annotate(args: argparse.Namespace) -> int:
    from carbody.annotate.server import serve
    from carbody.annotate.session import AnnotationSession
    from carbody.errors import AnnotationError

    if not 0 <= args.port <= 65535:
        raise AnnotationError(f"port {args.port} is not a port number (0–65535)")
    session = AnnotationSession(args.image, args.keypoints, args.out, view=args.view, coco=args.coco)
    serve(session, args.port, open_browser=not args.no_browser)
    return 0
