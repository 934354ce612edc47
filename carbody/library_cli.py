"""``carbody library``: the expanded model library's size and cache."""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("library", help="build or load the expanded model library (S, 840 x N)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.add_argument("--dir", type=Path, help="template folder (default: templates_step/)")
    p.add_argument("--no-cache", action="store_true", help="rebuild S instead of reading the disk cache")
    p.set_defaults(func=_library)


def _library(args) -> int:
    from carbody.library import Expansion, cache_dir, load_library

    start = time.perf_counter()
    lib = load_library(args.dir, use_cache=not args.no_cache)
    seconds = time.perf_counter() - start
    summary = {
        "templates": len(lib.template_names),
        "models": lib.n_models,
        "models_per_template": Expansion().models_per_template,
        "shape": list(lib.S.shape),
        "template_names": lib.template_names,
        "cache_dir": None if cache_dir() is None else str(cache_dir()),
        "load_seconds": round(seconds, 4),
    }
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        print(f"{summary['templates']} templates -> {summary['models']} models, S {lib.S.shape[0]} x "
              f"{lib.S.shape[1]}, loaded in {seconds:.3f} s (cache: {summary['cache_dir']})")
    return 0
