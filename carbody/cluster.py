"""The Dask cluster the many-photo commands run on (``carbody batch``, ``render-dataset``).

    from carbody.cluster import connect
    with connect(workers=2) as client:                 # a local cluster: 2 worker processes
        ...
    with connect(scheduler="tcp://10.0.0.5:8786") as client:   # one that is already running
        ...

Imported only by the commands that use Dask (``distributed`` loads with it).

Every worker runs one task at a time (one thread: the work is numpy, OCCT and VTK, a core's
worth each) and gets :class:`CarbodyWorker`, which pins one BLAS/OpenMP/torch thread (two
workers on two cores would otherwise oversubscribe them) and loads, once, what every photo
needs into the module-level caches the public API already reads
(:func:`carbody.library.default_library`, :func:`carbody.view.onnx_net.load_onnx_classifier`), so a
photo's task stays a plain call of :func:`carbody.reconstruct`.

The workers read the inputs and write the outputs themselves, so on a cluster of several
machines the photos, marks and output folder must lie on a file system every worker mounts at
the same path (:func:`check_shared_folder` refuses a cluster that does not see the output
folder). Nothing but task descriptions (paths and options, about a kilobyte) and one-line
results passes through the scheduler.
"""
from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import tempfile
import time
from pathlib import Path
from typing import Iterator

from distributed.diagnostics.plugin import WorkerPlugin

from carbody.errors import BatchError

#: What :func:`warm_up` can load: the model library, the view classifier (ONNX Runtime), and the
#: kernel (OCP for the surfaces and STEP, VTK for the pictures), whose imports take seconds.
WARM_PARTS = ("library", "classifier", "kernel")

#: How long to wait for a running cluster's scheduler to answer, and for its first worker to
#: join, seconds.
CONNECT_TIMEOUT_S = 10
FIRST_WORKER_TIMEOUT_S = 60

# The thread limit threadpoolctl keeps for this process (set by warm_up).
_THREAD_LIMITS = None


def default_workers() -> int:
    """The cores this process may run on (a local cluster's default worker count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def warm_up(parts: tuple[str, ...] = WARM_PARTS) -> dict[str, float]:
    """Load ``parts`` (:data:`WARM_PARTS`) into this process's caches and keep every math
    library to one thread; returns the seconds each took.

    Runs in each worker (:class:`CarbodyWorker`); calling it again costs nothing.
    """
    global _THREAD_LIMITS
    import cv2

    # OpenCV keeps a pool of its own (GrabCut), and the view classifier's session takes its
    # thread count from it when it is made (carbody.view.onnx_net): set it first.
    cv2.setNumThreads(1)
    seconds = {}
    for part in parts:
        start = time.perf_counter()
        if part == "library":
            from carbody.library import default_library

            default_library()
        elif part == "classifier":
            from carbody.view.onnx_net import load_onnx_classifier

            load_onnx_classifier()
        elif part == "kernel":
            import OCP  # noqa: F401  (the faces, the sewing and the STEP writers)
            import vtkmodules.vtkRenderingCore  # noqa: F401
            import vtkmodules.vtkRenderingOpenGL2  # noqa: F401

            import carbody.surface  # noqa: F401
        else:
            raise ValueError(f"unknown part {part!r} (known: {', '.join(WARM_PARTS)})")
        seconds[part] = time.perf_counter() - start
    # After the imports, so the BLAS and OpenMP libraries they loaded are limited too (a Dask
    # nanny also sets OMP/OPENBLAS/MKL_NUM_THREADS=1 for the processes it starts; a worker
    # started some other way may not have).
    from threadpoolctl import threadpool_limits

    _THREAD_LIMITS = threadpool_limits(1)
    return seconds


class CarbodyWorker(WorkerPlugin):
    """Sets up each worker once: :func:`warm_up` in a thread of its own, so the worker's event
    loop keeps answering the scheduler meanwhile; registering the plugin returns when every
    worker is warm, before the first task goes out (and a worker that joins later warms the
    same way)."""

    name = "carbody"

    def __init__(self, parts: tuple[str, ...] = WARM_PARTS):
        self.parts = tuple(parts)
        self.seconds: dict[str, float] = {}

    async def setup(self, worker):
        self.seconds = await asyncio.get_running_loop().run_in_executor(None, warm_up, self.parts)


@contextlib.contextmanager
def connect(scheduler: str | None = None, workers: int | None = None,
            warm: tuple[str, ...] = WARM_PARTS) -> Iterator:
    """A ``distributed.Client`` on a local cluster started for the run (``workers`` processes,
    default one per core, closed after) or on the running cluster at ``scheduler``; every
    worker warmed with ``warm`` (:func:`warm_up`) before it is handed out.

    Raises:
        BatchError: both or a bad number of workers given, a scheduler that cannot be reached,
            a cluster without workers, or workers that cannot load carbody.
    """
    from distributed import Client, LocalCluster

    if scheduler and workers:
        raise BatchError("give --scheduler or --workers, not both (a running cluster has its own workers)")
    if workers is not None and workers < 1:
        raise BatchError(f"--workers must be at least 1, got {workers}")
    with contextlib.ExitStack() as stack:
        if scheduler:
            try:
                client = stack.enter_context(Client(scheduler, timeout=CONNECT_TIMEOUT_S))
            except (OSError, asyncio.TimeoutError, TimeoutError, ValueError) as exc:
                raise BatchError(f"cannot reach the Dask scheduler at {scheduler} ({exc})") from None
            try:
                client.wait_for_workers(1, timeout=FIRST_WORKER_TIMEOUT_S)
            except (asyncio.TimeoutError, TimeoutError):
                raise BatchError(f"the Dask cluster at {scheduler} has no workers "
                                 f"(none joined in {FIRST_WORKER_TIMEOUT_S} s)") from None
        else:
            # Worker processes are spawned: they inherit this process's environment and
            # sys.path, so a source checkout on PYTHONPATH works as an installed package does.
            cluster = stack.enter_context(LocalCluster(
                n_workers=workers or default_workers(), threads_per_worker=1, processes=True,
                dashboard_address=":0", silence_logs=logging.ERROR))
            client = stack.enter_context(Client(cluster))
        try:
            client.register_plugin(CarbodyWorker(warm))
        except Exception as exc:  # noqa: BLE001  whatever a worker raised while loading carbody
            raise BatchError(f"the Dask workers could not load carbody ({type(exc).__name__}: {exc}); "
                             f"install it on every worker") from None
        yield client


def warm_up_seconds(client) -> dict[str, dict[str, float]]:
    """{worker address: {part: seconds}}: what each worker's :class:`CarbodyWorker` took."""
    def seconds(dask_worker) -> dict[str, float]:
        plugin = dask_worker.plugins.get(CarbodyWorker.name)
        return {k: round(v, 3) for k, v in getattr(plugin, "seconds", {}).items()}

    return client.run(seconds)


def check_shared_folder(client, folder: str | Path) -> None:
    """Make sure every worker of ``client`` sees ``folder`` (an existing folder) as this process
    does: a file made here must be there.

    Raises:
        BatchError: naming the workers that do not see it.
    """
    folder = Path(folder).resolve()
    with tempfile.NamedTemporaryFile(dir=folder, prefix=".carbody-shared-probe-") as probe:
        seen = client.run(os.path.exists, probe.name)
    blind = sorted(w for w, ok in seen.items() if not ok)
    if blind:
        raise BatchError(f"{len(blind)} of {len(seen)} Dask workers ({', '.join(blind[:3])}"
                         f"{', ...' if len(blind) > 3 else ''}) do not see {folder}: the photos and the "
                         f"output folder must be on a file system every worker mounts at the same path")
