"""``carbody batch``: every photo of a manifest reconstructed on a Dask cluster."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_parsers(sub: argparse._SubParsersAction) -> None:
    from carbody.batch import COLUMNS

    columns = "; ".join(f"{k}: {v}" for k, v in COLUMNS.items())
    p = sub.add_parser(
        "batch", help="reconstruct every photo of a manifest, on a local or running Dask cluster",
        description="Run `carbody reconstruct` on every photo of MANIFEST into OUT_DIR/NAME/ on a Dask "
                    "cluster: a local one (--workers processes, default one per core) or a running one "
                    "(--scheduler). MANIFEST is a CSV file with a header row, JSON lines (one object a "
                    "line), or a folder of photos each with a same-named .json marks file; paths are "
                    f"relative to its folder. Columns: {columns}. A photo whose folder is whole, from "
                    "the same row and newer than its photo and marks is skipped (run it again to "
                    "finish a stopped batch); each folder appears whole or not at all. A refused "
                    "photo is one line in the summary (on screen and OUT_DIR/batch.json) and the "
                    "rest go on. Exit code 0 when every photo is done or up to date, 1 when some "
                    "were refused or failed, 2 for a bad manifest or option.")
    p.add_argument("manifest", type=Path, help="CSV, JSON lines (.jsonl), or a folder of photos + .json marks")
    p.add_argument("-o", "--out", required=True, type=Path, help="output folder (OUT_DIR/NAME/ per photo)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="a running Dask cluster's scheduler (tcp://host:8786); its workers must see the "
                        "photos and OUT_DIR at the same paths and have carbody installed")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes of the local cluster (default: one per core)")
    p.add_argument("--force", action="store_true", help="redo photos that are up to date too")
    p.set_defaults(func=run_batch_command)


def run_batch_command(args: argparse.Namespace, out=sys.stdout) -> int:
    from carbody.batch import SUMMARY_FILE, run_batch

    try:
        summary = run_batch(args.manifest, args.out, args.scheduler, args.workers, force=args.force,
                            progress=not args.quiet)
    except KeyboardInterrupt:
        # batch.json already says which photos were done; their folders are whole
        print(f"carbody batch: stopped; {args.out / SUMMARY_FILE} lists what was done; run the same "
              f"command again to finish the rest", file=sys.stderr)
        return 130  # 128 + SIGINT
    print(summary.table(), file=out)
    print(f"summary in {summary.out_dir / 'batch.json'}", file=out)
    return 0 if summary.ok else 1
