"""The full fit's worker: a separate Python process (``python -m carbody.annotate.worker``).

A process rather than a thread: the fit is Python-heavy, and in a thread of the server it would
hold back the next click's quick fit. A plain child process talking JSON lines on its stdin and
stdout rather than :mod:`multiprocessing`: it does not re-import the caller's main script, so
the page works the same from the ``carbody`` command, a notebook or a test.

Each request is one line ``{"id", "marks", "image_size", "prior"}``; each answer one line
``{"id", "payload"}`` (:func:`carbody.annotate.live_fit.full_fit_payload`) or ``{"id",
"error"}``; the first line, ``{"ready": true}``, says the child has warmed up. The parent
(:class:`FullFitWorker`) keeps at most one request in flight.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from dataclasses import asdict, fields
from pathlib import Path
from typing import Callable


def prior_to_json(prior) -> dict | None:
    """A view prior (None, a :class:`~carbody.camera.View` or a :class:`~carbody.fit.ViewPrior`)
    as JSON."""
    from carbody.camera import View

    if prior is None:
        return None
    kind = "view" if isinstance(prior, View) else "prior"
    return {"kind": kind, **asdict(prior)}


def prior_from_json(data: dict | None):
    """The inverse of :func:`prior_to_json`."""
    from carbody.camera import View
    from carbody.fit import ViewPrior

    if data is None:
        return None
    cls = View if data["kind"] == "view" else ViewPrior
    values = {f.name: data[f.name] for f in fields(cls) if f.name in data}
    for name, value in values.items():
        if isinstance(value, list):
            values[name] = tuple(value)
    return cls(**values)


class FullFitWorker:
    """The parent's end: start the child, send a fit, get its payload back on a callback.

    Args:
        on_result: called (from a reader thread) with (request id, payload or None on error).
    """

    def __init__(self, on_result: Callable[[int, dict | None], None]):
        import carbody

        root = str(Path(carbody.__file__).resolve().parents[1])
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
        self._proc = subprocess.Popen([sys.executable, "-m", "carbody.annotate.worker"], stdin=subprocess.PIPE,
                                      stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env,
                                      bufsize=1)
        self._on_result = on_result
        self.ready = threading.Event()  # set when the child has warmed up
        self._write = threading.Lock()
        threading.Thread(target=self._read, daemon=True, name="carbody-full-fit-reader").start()

    def submit(self, request_id: int, marks: dict, image_size: tuple[int, int], prior) -> bool:
        """Send one fit; False when the worker is gone."""
        line = json.dumps({"id": request_id, "marks": {n: list(uv) for n, uv in marks.items()},
                           "image_size": list(image_size), "prior": prior_to_json(prior)})
        with self._write:
            try:
                self._proc.stdin.write(line + "\n")
                self._proc.stdin.flush()
            except (BrokenPipeError, ValueError, OSError):
                return False
        return True

    def _read(self) -> None:
        for line in self._proc.stdout:
            try:
                answer = json.loads(line)
            except json.JSONDecodeError:
                continue
            if answer.get("ready"):
                self.ready.set()
                continue
            self._on_result(int(answer["id"]), answer.get("payload"))

    def close(self) -> None:
        """End the child: its stdin closed (it leaves when it reads the end), and stopped if it is
        still busy a moment later (a fit writes nothing: nothing is lost)."""
        try:
            self._proc.stdin.close()
        except OSError:
            pass
        try:
            self._proc.wait(timeout=0.5)
        except subprocess.TimeoutExpired:
            self._proc.terminate()
            try:
                self._proc.wait(timeout=2)
            except subprocess.TimeoutExpired:
                self._proc.kill()


def main() -> None:
    """The child: answer fits until stdin closes."""
    from carbody.annotate import live_fit

    live_fit.warm_worker()
    sys.stdout.write(json.dumps({"ready": True}) + "\n")
    sys.stdout.flush()
    for line in sys.stdin:
        request = None
        try:
            request = json.loads(line)
            marks = {n: (float(u), float(v)) for n, (u, v) in request["marks"].items()}
            payload = live_fit.full_fit_payload(marks, tuple(request["image_size"]), prior_from_json(request["prior"]))
            answer = {"id": request["id"], "payload": payload}
        except Exception as exc:  # one bad fit must not end the worker
            answer = {"id": request.get("id", -1) if isinstance(request, dict) else -1, "error": str(exc)}
        sys.stdout.write(json.dumps(answer) + "\n")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
