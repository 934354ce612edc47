"""Library load time: cold (read every template STEP file, normalise, expand) and warm (disk cache).

Run: .venv/bin/python benchmarks/bench_library.py   (prints a Markdown table)
"""
from __future__ import annotations

import os
import platform
import statistics
import tempfile
import time


def main() -> None:
    os.environ["CARBODY_CACHE_DIR"] = tempfile.mkdtemp(prefix="carbody-bench-")
    from carbody.library import load_library

    start = time.perf_counter()
    lib = load_library()
    cold = time.perf_counter() - start
    warm = []
    for _ in range(20):
        start = time.perf_counter()
        load_library()
        warm.append(time.perf_counter() - start)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    print(f"library: {len(lib.template_names)} templates -> {lib.n_models} models, S {lib.S.shape}")
    print("| load | seconds |\n|---|---|")
    print(f"| cold (STEP read + normalise + expand + cache write) | {cold:.3f} |")
    print(f"| warm (cache), median of 20 | {statistics.median(warm):.4f} |")
    print(f"| warm (cache), max of 20 | {max(warm):.4f} |")


if __name__ == "__main__":
    main()
