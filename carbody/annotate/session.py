"""One photo being marked: the marks, the fits, the keypoint asked for, saving and reconstructing.

:class:`AnnotationSession` is everything the page does, without the page: the server
(:mod:`carbody.annotate.server`) turns each request into one call, and the benchmark and the
tests drive it directly. Every edit (a mark placed, moved, removed or hidden, a view picked)
bumps the session's ``revision`` and refits at once with the quick fit
(:mod:`carbody.annotate.live_fit`); the full fit then runs in a worker process while the page is
idle and replaces the quick one if no edit came meanwhile (a stale one is dropped). A worker
process, not a thread: the full fit is Python-heavy, and in a thread it would hold back the next
click's quick fit.

Before the car is fitted, the view the page draws the reference car from and asks keypoints for
is a guess: the view classifier's (run when the session starts, in the background, on the whole
photo, then weighed by the names of the marks placed so far), a view the user picks, or
``--view``.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from carbody.annotate import guide, live_fit
from carbody.annotate.marks import MarkSheet, check_output, coco_path_for
from carbody.camera import View
from carbody.errors import CarbodyError, KeypointError

#: The view guessed before the classifier answers (a front three-quarter view, the commonest).
DEFAULT_VIEW = View(30.0, 5.0)

#: The page says the fit has settled when every keypoint still to ask is predicted within this
#: fraction of the car's length in the photo (a careful click's accuracy: the real photos'
#: marks are 1–1.5 % off, ``../shared/realphotos``).
SETTLED_FRACTION = 0.01

#: The full fit starts this long after the last edit (seconds): clicks in a quick run do not
#: each start one.
FULL_FIT_DELAY_S = 0.25


@dataclass
class Reconstruction:
    """A reconstruction the page started: its state (``"running"``, ``"done"``, ``"failed"``),
    the stage it is at, the folder, its files and its error."""

    state: str = "idle"
    stage: str = ""
    folder: str | None = None
    files: list[str] | None = None
    error: str | None = None
    summary: str | None = None


class AnnotationSession:
    """The marks of one photo and their fits (module docstring).

    Args:
        image: the photo's path.
        keypoints: a keypoint file to start from (its marks appear as placed), or None.
        output: where Save writes the project's JSON (default: ``keypoints`` when it is the
            project's JSON, else
            ``IMAGE_keypoints.json`` beside the photo).
        view: the view to start from (degrees or a name), instead of the classifier's guess.
        classify: run the view classifier for the first guess (off: ``DEFAULT_VIEW``).
        full_fits: run the full fit in a worker process when idle (off: the quick fit alone).
        coco: Save also writes COCO keypoints (``NAME.coco.json``).
        warm_up: fit the reference car once in the background at the start (and start the
            worker), so that the first fit of the photo is as quick as the rest.
    Raises:
        ImageError, KeypointError, OutputError, AngleError: a bad photo, keypoint file, output
            or view, in one line.
    """

    def __init__(self, image: str | Path, keypoints: str | Path | None = None,
                 output: str | Path | None = None, view: float | str | None = None,
                 classify: bool = True, full_fits: bool = True, coco: bool = False, warm_up: bool = True):
        from carbody.camera import check_azimuth, read_view
        from carbody.view.predict import read_image

        self.image_path = Path(image)
        self.rgb = read_image(self.image_path)
        h, w = self.rgb.shape[:2]
        self.image_size = (w, h)
        if keypoints is not None:
            self.sheet = MarkSheet.load(keypoints, self.image_path.name, self.image_size)
        else:
            self.sheet = MarkSheet(self.image_path.name, self.image_size)
        default = Path(keypoints) if keypoints is not None and self.sheet.from_project_json else \
            self.image_path.with_name(f"{self.image_path.stem}_keypoints.json")
        self.output = check_output(output if output is not None else default)
        self.coco = coco
        self._lock = threading.RLock()
        self._changed = threading.Condition(self._lock)
        self.revision = 0
        self.inputs_revision = 0  # the last edit that changed what is fitted (the marks, the prior)
        self.view_source = "default"
        self.guess = DEFAULT_VIEW
        self.prior = None
        self.classifier_probabilities: np.ndarray | None = None  # (24,), once the classifier answers
        if view is not None:
            self.guess = View(check_azimuth(read_view(view)), DEFAULT_VIEW.elevation)
            self.prior, self.view_source = self.guess, "told"
        self.quick: live_fit.LiveFit | None = None
        self.payload: dict = live_fit.fit_payload(live_fit.LiveFit(None, None, True, 0.0), {})
        self.payload_revision = 0
        self.full_revision = -1  # the inputs_revision whose full fit has landed
        self.reconstruction = Reconstruction()
        self.saved_revision: int | None = None
        self._worker = None
        self._in_flight: int | None = None
        self._timer: threading.Timer | None = None
        self.full_fits = full_fits
        self._closed = False
        self._background: list[threading.Thread] = []
        if warm_up:
            self._background.append(threading.Thread(target=live_fit.warm_up, daemon=True, name="carbody-warm-up"))
            if full_fits:
                from carbody.annotate.worker import FullFitWorker

                self._worker = FullFitWorker(self._full_fit_done)
        if classify and view is None:
            self._background.append(threading.Thread(target=self._classify, daemon=True, name="carbody-classify"))
        for thread in self._background:
            thread.start()
        with self._lock:
            self._refit()

    def wait_started(self, timeout: float = 60.0) -> None:
        """Wait for the start-up work in the background (the warm-up fits here and in the
        worker, the classifier)."""
        deadline = time.monotonic() + timeout
        for thread in self._background:
            thread.join(max(0.0, deadline - time.monotonic()))
        if self._worker is not None:
            self._worker.ready.wait(max(0.0, deadline - time.monotonic()))

    # ---- the view guess

    def _classify(self) -> None:
        """The view classifier's guess and prior (a failure leaves the default guess)."""
        try:
            from carbody.view.predict import predict_view

            prediction = predict_view(self.rgb)
        except Exception:  # no weights, no torch: the page works without the guess
            return
        self.use_classifier(prediction.probabilities)

    def use_classifier(self, probabilities) -> None:
        """The classifier's (24,) class probabilities as the guess and the fits' prior, unless
        the user picked a view meanwhile or one was told."""
        from carbody.fit import ViewPrior
        from carbody.view.labels import CLASS_ANGLES_DEG

        with self._lock:
            if self.view_source != "default":
                return
            self.classifier_probabilities = np.asarray(probabilities, dtype=float)
            self.prior = ViewPrior.from_classifier(CLASS_ANGLES_DEG, self.classifier_probabilities)
            self.view_source = "classifier"
            self._edited()

    def _classifier_guess(self) -> View:
        """The classifier's view weighed by the names marked so far (:mod:`carbody.view.marks`:
        a person marks what they see), as the page guesses it before the first fit. The prior
        of the fits stays the classifier's alone, as ``carbody reconstruct`` has it."""
        from carbody.view.labels import continuous_estimate
        from carbody.view.marks import combine_with_marks

        p = combine_with_marks(self.classifier_probabilities, list(self.sheet.marks))
        return View(continuous_estimate(p), DEFAULT_VIEW.elevation)

    def pick_view(self, azimuth_deg: float) -> dict:
        """The user says which way the car faces: the guess and the fit's prior from now on."""
        from carbody.camera import check_azimuth

        with self._lock:
            self.guess = View(check_azimuth(float(azimuth_deg)) % 360.0, DEFAULT_VIEW.elevation)
            self.prior, self.view_source = self.guess, "picked"
            self.quick = None  # the next fit starts from the view picked, not the last fit's
            return self._edited()

    # ---- edits

    def place(self, name: str, uv: tuple[float, float]) -> dict:
        """Place (or move) ``name``'s mark at ``uv`` photo pixels; the new state."""
        with self._lock:
            self.sheet.place(name, uv)
            return self._edited()

    def remove(self, name: str) -> dict:
        """Remove ``name``'s mark or hidden flag; the new state."""
        with self._lock:
            marked = name in self.sheet.marks
            self.sheet.remove(name)
            return self._edited(refit=marked)

    def hide(self, name: str) -> dict:
        """Say the photo does not show ``name``; the new state (refitted only when it was marked:
        an H press on a keypoint asked changes nothing the fit reads, and answers at once)."""
        with self._lock:
            marked = name in self.sheet.marks
            self.sheet.hide(name)
            return self._edited(refit=marked)

    def accept(self, name: str) -> dict:
        """Place ``name`` where its ghost is (Enter on the page); the new state.

        Raises:
            KeypointError: ``name`` has no ghost.
        """
        with self._lock:
            ghost = (self.payload.get("ghosts") or {}).get(name)
            if ghost is None:
                raise KeypointError(f"keypoint {name!r} has no predicted position to accept")
            self.sheet.place(name, tuple(ghost["uv"]))
            return self._edited()

    def _edited(self, refit: bool = True) -> dict:
        """A new revision; the marks refitted when ``refit`` (the fit's inputs changed), else the
        fit stays the current one (and refined if it was)."""
        self.revision += 1
        if self.view_source == "classifier":
            self.guess = self._classifier_guess()
        if refit:
            self.inputs_revision = self.revision
            self._refit()
        else:
            self.payload_revision = self.revision
            self._changed.notify_all()
        return self.state()

    def _refit(self) -> None:
        """The quick fit of the marks as they are now (caller holds the lock), then the full fit
        scheduled. After the first fit, the quick one is told the last fit's view (a prior: the
        scan still goes round the car) and scans at its elevation and perspective."""
        from carbody.fit import ViewPrior

        marks = dict(self.sheet.marks)
        last = None if self.quick is None or self.quick.fit is None else self.quick.fit.view
        if last is not None:
            live = live_fit.fit_marks(marks, self.image_size, ViewPrior.told(last), last, quick=True)
        else:
            live = live_fit.fit_marks(marks, self.image_size, self.prior, self._start_view(), quick=True)
        if live.fit is not None or len(marks) < live_fit.MIN_MARKS:
            self.quick = live
        self.payload = live_fit.fit_payload(live, marks)
        self.payload_revision = self.revision
        self._changed.notify_all()
        if self.full_fits and live.fit is not None:
            self._schedule_full_fit()

    def _start_view(self) -> View:
        """Where the first quick fit scans: the guess, at a typical photo's distance (2.5
        wheelbases, normalised units)."""
        return View(self.guess.azimuth, self.guess.elevation, 0.0, 2500.0, (0.0, 500.0, 200.0))

    # ---- the full fit, in a worker process

    def _schedule_full_fit(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
        self._timer = threading.Timer(FULL_FIT_DELAY_S, self._start_full_fit, args=(self.inputs_revision,))
        self._timer.daemon = True
        self._timer.start()

    def _start_full_fit(self, revision: int) -> None:
        """Send the marks of inputs ``revision`` to the worker, unless it is busy (the fit then
        starts when it answers) or the marks have changed since."""
        with self._lock:
            if revision != self.inputs_revision or self._closed or self._in_flight is not None:
                return
            if self._worker is None:
                from carbody.annotate.worker import FullFitWorker

                self._worker = FullFitWorker(self._full_fit_done)
            self._in_flight = revision
            if not self._worker.submit(revision, dict(self.sheet.marks), self.image_size, self.prior):
                self._in_flight = None

    def _full_fit_done(self, revision: int, payload: dict | None) -> None:
        with self._lock:
            self._in_flight = None
            if revision == self.inputs_revision:
                if payload is not None and payload["ok"]:
                    self.payload = payload
                    self.payload_revision = self.revision
                self.full_revision = revision
                self._changed.notify_all()
            elif self.quick is not None and self.quick.fit is not None:
                # stale: an edit came while it ran; fit the marks as they are now
                self._schedule_full_fit()

    def wait_refined(self, revision: int, timeout: float = 10.0) -> dict | None:
        """The state once the full fit of the marks of ``revision`` has landed; None when another
        edit came first or it did not land within ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        with self._lock:
            while not self.refined and self.revision == revision and not self._closed:
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._changed.wait(left)
            return self.state() if self.refined and self.revision == revision else None

    @property
    def refined(self) -> bool:
        """Whether the page shows the full fit of the marks as they are."""
        return self.full_revision == self.inputs_revision

    def refine_now(self) -> dict:
        """Run the full fit of the marks as they are, in this process (the benchmark, the tests)."""
        with self._lock:
            live = live_fit.fit_marks(dict(self.sheet.marks), self.image_size, self.prior, quick=False)
            if live.fit is not None:
                self.quick = live
                self.payload = live_fit.fit_payload(live, self.sheet.marks)
                self.payload_revision, self.full_revision = self.revision, self.inputs_revision
            return self.state()

    # ---- what the page shows

    @property
    def view(self) -> View:
        """The fitted view, or the guess before a fit."""
        fit = self.quick.fit if self.quick is not None else None
        return fit.view if fit is not None else self.guess

    def ask_order(self) -> list[str]:
        """The keypoints to ask for, first first (:func:`carbody.annotate.guide.ask_order`)."""
        ghosts = self.payload.get("ghosts") if self.payload.get("ok") else None
        return guide.ask_order(self.view, self.sheet.marks, self.sheet.hidden, ghosts)

    def settled(self) -> bool:
        """Whether every keypoint still to ask is predicted within a careful click
        (``SETTLED_FRACTION`` of the car's length in the photo)."""
        if not self.payload.get("ok"):
            return False
        ghosts = self.payload["ghosts"]
        left = [ghosts[n]["sd_px"] for n in self.ask_order()]
        return max(left, default=0.0) <= SETTLED_FRACTION * self.payload["car_length_px"]

    def state(self) -> dict:
        """Everything the page draws, JSON-ready."""
        with self._lock:
            view = self.view
            return {
                "revision": self.revision, "fit_revision": self.payload_revision,
                "refined": self.refined,
                "image": self.sheet.image, "image_size": list(self.image_size),
                "marks": {n: [float(u), float(v)] for n, (u, v) in self.sheet.marks.items()},
                "hidden": sorted(self.sheet.hidden),
                "loaded_unmoved": sorted(self.sheet.loaded),
                "view": {"azimuth_deg": float(view.azimuth) % 360.0, "elevation_deg": float(view.elevation),
                         "source": "fit" if self.payload.get("ok") else self.view_source},
                "ask": self.ask_order(), "settled": self.settled(), "fit": self.payload,
                "output": str(self.output), "coco_output": str(coco_path_for(self.output)) if self.coco else None,
                "saved": self.saved_revision == self.revision,
                "reconstruction": vars(self.reconstruction).copy(),
            }

    # ---- saving and reconstructing

    def save(self, coco: bool | None = None) -> list[Path]:
        """Write the marks to ``output`` (and COCO beside it when asked); the files written."""
        with self._lock:
            want = self.coco if coco is None else coco
            files = self.sheet.save(self.output, coco_path_for(self.output) if want else None)
            self.saved_revision = self.revision
            return files

    def start_reconstruction(self, folder: str | Path | None = None) -> dict:
        """Run ``carbody.reconstruct`` on the marks into ``folder`` (default ``IMAGE_carbody``
        beside the output), in a background thread; the state."""
        from carbody.pipeline import prepare_output_dir

        with self._lock:
            if self.reconstruction.state == "running":
                return self.state()
            if len(self.sheet.marks) < live_fit.MIN_MARKS:
                raise KeypointError(f"{len(self.sheet.marks)} keypoint(s) marked; the fit needs at least {live_fit.MIN_MARKS}")
            out = Path(folder) if folder else self.output.with_name(f"{self.image_path.stem}_carbody")
            prepare_output_dir(out)
            marks = dict(self.sheet.marks)
            view = self.view if self.payload.get("ok") else None
            self.reconstruction = Reconstruction("running", "starting", str(out))
        threading.Thread(target=self._reconstruct, args=(marks, view, out), daemon=True,
                         name="carbody-reconstruct").start()
        return self.state()

    def _reconstruct(self, marks: dict, view: View | None, out: Path) -> None:
        import carbody

        def on_stage(label: str) -> None:
            self.reconstruction.stage = label

        try:
            # the view fitted so far as the prior (the search still looks all round the car)
            result = carbody.reconstruct(self.image_path, marks, None if view is None else float(view.azimuth) % 360.0,
                                         elevation_deg=0.0 if view is None else float(view.elevation),
                                         on_stage=on_stage)
            on_stage("write")
            paths = result.write(out)
            summary = (out / "summary.txt").read_text()
        except CarbodyError as exc:
            self.reconstruction = Reconstruction("failed", "", str(out), error=str(exc))
            return
        except Exception as exc:  # a bug must not leave the page waiting
            self.reconstruction = Reconstruction("failed", "", str(out), error=f"{type(exc).__name__}: {exc}")
            return
        self.reconstruction = Reconstruction("done", "", str(out), sorted(p.name for p in paths.values()),
                                             summary=summary)

    def close(self) -> None:
        """Stop the full-fit worker."""
        with self._lock:
            self._closed = True
            if self._timer is not None:
                self._timer.cancel()
            self._changed.notify_all()
        if self._worker is not None:
            self._worker.close()

