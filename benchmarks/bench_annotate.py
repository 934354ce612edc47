"""The annotation page: how fast each click's update comes back, and how many clicks the guided
page needs to reach the fit of marking everything by hand.

A simulated user marks a photo through the page's own server (``carbody annotate``'s
:class:`~carbody.annotate.server.AnnotationServer`, in this process, over HTTP on 127.0.0.1; the
full fit in its worker process), knowing the photo's hand marks (the example's 35, or a real
photo's file in ``../shared/realphotos``). The page starts as a user opens it: the view
classifier guesses the view, and the user picks the nearest of the page's eight views when the
guess is more than 30° off the view the hand marks fit (one action). Then, keypoint after
keypoint, the one the page asks for:

- a keypoint the hand marks have: **accept** its ghost (Enter) when the ghost lies within
  ``--accept`` (1 %) of the car's length in the photo from the hand mark — as close as a careful
  click is (the real photos' marks are 1–1.5 % off) —, else **click** it at the hand mark (or
  drag the ghost there: one action either way);
- a keypoint the hand marks lack (the annotator could not see it or was unsure): **H**, hidden.

With ``--user ghosts`` the user fixes the ghosts first, as the page invites: once ghosts are drawn,
while one of a keypoint they can see (one the hand marks have) lies more than ``--accept`` off its
hand mark, they **drag** the one furthest off onto it (a person sees which sits furthest from its
point). When every such ghost is within a click, they stop: the fit sits on every point they
can see, and accepting a ghost where it is teaches the fit nothing. The **ghosts-any** user
(``--user ghosts-any --seed N``) drags any ghost more than ``--accept`` off, picked at random:
a person who does not judge which is furthest. With ``--notice F`` it picks only among the ghosts
at least F times as far off as the furthest: a person who sees which are badly off, not which
is worst.

Every action counts one, as an accepted ghost counts one key press. The user looks at each
update: the next action waits for the full fit (the page's second update). When the page says
the fit has settled, the user stops, as the page tells a real user they can (``--to-the-end``:
the user goes on until nothing is asked, the rule before; accepting every ghost then pulls the
car toward its own guess).

Definitions:

- **Hand**: the number of hand marks (marking everything by hand: one click each).
- **The same fit**: the full fit (:func:`carbody.fit.fit_wireframe`, camera distance found,
  the session's view prior) of the marks placed so far is as close to the full fit of all the
  hand marks as marking everything again is. Its distances from the hand fit are d3, the mean
  3D distance of its keypoints (the 35 left ones, each car at the hand fit's wheelbase), and
  d2, that of its projected keypoints (those the hand fit shows). ``--draws`` (12) re-markings
  of the hand marks, each mark moved by ``--accept`` of isotropic click noise (RMS radius), give
  τ3 and τ2, the means of the same distances. The fit's score is d3/τ3 + d2/τ2; it is the same
  when that is at most the median re-marking's score, as close as marking everything again is
  at least half the time. (The rule before, both distances within their means, was stricter
  than that: the table's last column counts the re-markings that meet each rule, each judged
  by the others; its column "earlier rule" counts the actions by it.)
- **Same at**: the first action count after which the fit is the same and stays the same to
  the user's last action; **first fit at**: the action that placed the fifth mark (the page fits from there
  on); **settled at**: the first action count at which the page says the fit has settled
  (every keypoint still asked predicted within 1 % of the car's length), with the fit's
  distances there.
- **Oracle** (``--oracle``): how many of the hand marks the best order needs, found greedily:
  the five hand marks farthest apart in the photo, then each time the hand mark whose addition
  brings the full fit nearest the hand fit (distances over τ3 plus over τ2), until the fit is
  the same. Even a page that never asked for what the annotator left out would need about
  that many actions. With ``--with-wheels`` every fit of it (the hand fit and τ too) is given
  the photo, so the wheels' hubs found there join the marks, as ``carbody reconstruct`` fits:
  does the photo's own evidence let fewer marks reach the hand fit? ``--with-outline`` gives
  every fit the car's outline in the photo as well (``reconstruct --outline``, wheels on too).
- **A detector's key** (``--detector PCT ... [--detector-net W.pt]``): one key places keypoints
  where a detector puts them, then the user puts right the mark furthest off while one is more
  than ``--accept`` off. The detectors: the hand marks moved
  at random by PCT % of the car's length at the median (every hand mark placed), and ``benchmarks/probe_keypoints.py``'s
  network (reading the hand marks' box taken lower, as a box dragged round the car would be,
  and the photo mirrored too). The network's key places every keypoint whose heat map peaks at
  ``--detector-peak`` (0.3) or more: some the annotator left out, which the user removes when
  they lie more than ``--accept`` off the hand fit's; a hand-marked keypoint it left out is a
  ghost, dragged as the others. With ``--detector-hand-names`` it places the hand-marked
  keypoints and no other, as the moved hand marks do. "Same at" counts the key as one action.
- **Facing** (``--facing``): on every real photo, the keypoints the full fit of its hand marks
  shows on the photo, by how squarely they face the camera
  (:func:`carbody.annotate.guide.facing_cosines`), and the share the annotator marked.
- **Quick against full** (``--quick-vs-full``): on the example and every real photo, its hand
  marks added in the file's order, the quick fit of each count (told the last quick fit's view,
  as the page does) against the full fit of the same marks, at every ``--every``-th count and
  all: the quick fit's processor time, how far its keypoints lie from the full fit's (median
  over the keypoints, % of the car's length in the photo) and how often its view is more than
  30° from the full fit's. Each time for the quick policy and for the one before commit 5db2425
  (six views ranked, the noise read again on the full grid), fitted one after the other.
- **Latency**: wall-clock from sending an edit to having its answer parsed (the update the page
  draws; the page's own drawing adds a few ms), for edits with five marks or more (a fit). Two
  runs: *paused* (the guided sessions above: the worker idle when the click comes) and *brisk*
  (``--brisk N`` clicks of the example in the page's order, each sent as soon as the last
  answer came: the worker still fitting the click before). Clicks and accepts (a quick fit
  each) apart from H presses (answered with the fit there is). The full fit's time is from the
  edit to its landing. The quick fit's *processor time* (its thread's) is what the update costs
  on an idle machine: a busy one stretches the wall clock, not that; the server's processor time
  per click adds the page's state and its JSON to it. How far the quick fit's
  keypoints (ghosts and reprojected marks) lie from the full fit's that replaces it, median
  over the keypoints, per edit.

    python benchmarks/bench_annotate.py [--photos cps_te66 cps_te39 cps_car10] [--data DIR]
                                        [--draws 6] [--accept 0.01] [--brisk 20] [--json FILE]
                                        [--oracle [--with-wheels | --with-outline]] [--facing] [--no-guided] [--to-the-end]
                                        [--detector PCT ... [--detector-net W.pt]]
                                        [--quick-vs-full [--every 3]]
                                        [--user asked|ghosts|ghosts-any [--notice F] [--seed N]]

Real photos are read where they are (``--data``, default ``../shared/realphotos``); a photo or
folder that is missing is skipped with a note. Run it niced on a shared machine: the load
averages are printed with the tables.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

DEFAULT_PHOTOS = ("cps_te66", "cps_te39", "cps_car10")
LATENCY_TARGET_MS = 300.0


class Client:
    """The page's requests, from Python."""

    def __init__(self, server):
        self.url, self.token = server.url, server.token

    def _call(self, path: str, body: dict | None = None):
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(self.url + path, data=data, headers={
            "Content-Type": "application/json", "X-Carbody-Token": self.token})
        with urllib.request.urlopen(req, timeout=60) as r:
            raw = r.read()
            self.server_cpu_ms = float(r.headers.get("X-Carbody-CPU-ms") or "nan")
        return json.loads(raw) if raw else None

    def state(self) -> dict:
        return self._call("api/state")

    def edit(self, **body) -> tuple[dict, float]:
        start = time.perf_counter()
        state = self._call("api/edit", body)
        return state, (time.perf_counter() - start) * 1000.0

    def refined(self, revision: int) -> dict | None:
        return self._call(f"api/refined?revision={revision}")


def angular(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


class Reference:
    """The fit of every hand mark, and how far re-marking everything moves it (τ3, τ2)."""

    def __init__(self, marks: dict, image_size, prior, accept: float, draws: int, seed: int = 0, photo=None,
                 outline: bool = False):
        from carbody.annotate import live_fit

        self.image_size, self.prior, self.photo, self.outline = image_size, prior, photo, outline
        self.fit = self.fit_marks(marks)
        self.shown = live_fit.visible_names(self.fit)
        self.k3, self.k2 = self.keypoints(self.fit)
        self.length_px = float(np.ptp(np.array(live_fit.projected_wireframe(self.fit)).reshape(-1, 2)[:, 0]))
        rng = np.random.default_rng(seed)
        sigma = accept * self.length_px / np.sqrt(2.0)  # per coordinate: RMS radius accept × length
        w, h = image_size
        spread = []
        for _ in range(draws):
            noisy = {n: tuple(np.clip(np.add(uv, rng.normal(0.0, sigma, 2)), 0, [w, h])) for n, uv in marks.items()}
            fit = self.fit_marks(noisy)
            spread.append(self.distances(fit))
        self.set_spread(spread)

    def set_spread(self, spread: list[tuple[float, float]]) -> None:
        """τ3, τ2 (the re-markings' mean distances) and the median re-marking's score, from the
        re-markings' (3D mm, photo px) distances from the hand fit."""
        self.spread = [tuple(d) for d in spread]
        self.tau3, self.tau2 = (float(v) for v in np.mean(spread, axis=0))
        self.bar = float(np.median([self.score(*d) for d in spread]))

    def score(self, d3: float, d2: float) -> float:
        """d3/τ3 + d2/τ2: the distances from the hand fit, each in units of a re-marking's mean."""
        return d3 / self.tau3 + d2 / self.tau2

    def same(self, d3: float, d2: float) -> bool:
        """The fit at distances (d3, d2) is as close as the median re-marking (NaN: no fit: not)."""
        return bool(self.score(d3, d2) <= self.bar)

    def same_earlier_rule(self, d3: float, d2: float) -> bool:
        """The rule before: both distances within the re-markings' means."""
        return bool(d3 <= self.tau3 and d2 <= self.tau2)

    def remarkings_passing(self) -> tuple[int, int, int]:
        """(by the score, by the earlier rule, draws): the re-markings that pass, each judged by
        the others (its own draw left out of τ3, τ2 and the median)."""
        d = np.array(self.spread)
        by_score = by_rule = 0
        for i in range(len(d)):
            rest = np.delete(d, i, axis=0)
            t3, t2 = rest.mean(axis=0)
            bar = np.median(rest[:, 0] / t3 + rest[:, 1] / t2)
            by_score += bool(d[i, 0] / t3 + d[i, 1] / t2 <= bar)
            by_rule += bool(d[i, 0] <= t3 and d[i, 1] <= t2)
        return by_score, by_rule, len(d)

    def fit_marks(self, marks: dict):
        """The full fit of ``marks`` (given the photo, and its outline, too when the reference
        was), or None."""
        from carbody.annotate import live_fit

        return live_fit.fit_marks(marks, self.image_size, self.prior, quick=False, photo=self.photo,
                                  outline=self.outline).fit

    def keypoints(self, fit) -> tuple[np.ndarray, np.ndarray]:
        from carbody.annotate import live_fit

        scale = self.fit.wheelbase_mm / fit.wheelbase_mm  # each car at the hand fit's wheelbase
        k3 = np.array(list(fit.wireframe.keypoints().values())) * scale
        points = live_fit.keypoint_positions(fit)
        k2 = fit.project_points(np.array([points[n] for n in self.shown]))
        return k3, k2

    def projected(self, fit) -> dict[str, np.ndarray]:
        """{name: (2,) photo px} of every keypoint name on ``fit`` (the hand fit's when None)."""
        from carbody.annotate import live_fit

        fit = self.fit if fit is None else fit
        points = live_fit.keypoint_positions(fit)
        names = list(points)
        return dict(zip(names, fit.project_points(np.array([points[n] for n in names]))))

    def distances(self, fit) -> tuple[float, float]:
        """(3D mm, photo px) mean keypoint distances of ``fit`` from the hand fit."""
        if fit is None:
            return float("nan"), float("nan")
        k3, k2 = self.keypoints(fit)
        return float(np.mean(np.linalg.norm(k3 - self.k3, axis=1))), float(np.mean(np.linalg.norm(k2 - self.k2, axis=1)))


def guided_session(name: str, image: Path, marks_file: Path, args) -> dict:
    """One simulated user marking one photo (module docstring)."""
    from carbody.annotate import live_fit
    from carbody.annotate.server import VIEW_CHOICES, AnnotationServer
    from carbody.annotate.session import AnnotationSession
    from carbody.fit import read_keypoints

    hand = read_keypoints(marks_file).points
    with tempfile.TemporaryDirectory() as tmp:
        session = AnnotationSession(image, output=Path(tmp) / "marks.json")
        session.wait_started(120)
        server = AnnotationServer(session)
        server.serve_in_thread()
        client = Client(server)
        try:
            ref = Reference(hand, session.image_size, session.prior, args.accept, args.draws)
            state = client.state()
            actions, rows, latencies, refined_s, quick_cpu, quick_off, server_cpu = 0, [], [], [], [], [], []
            guess = state["view"]["azimuth_deg"]
            picked = None
            if angular(guess, ref.fit.view.azimuth) > 30.0:
                picked = min(VIEW_CHOICES, key=lambda a: angular(a, ref.fit.view.azimuth))
                state, _ = client.edit(op="view", azimuth=picked)
                actions += 1
            accept_px = args.accept * ref.length_px
            stopped_on_ghosts = False
            pick = np.random.default_rng(args.seed)
            while state["ask"] and not (state["settled"] and not args.to_the_end):
                op, asked, body = next_action(state, hand, accept_px, args.user, pick, args.notice)
                if op == "stop":
                    stopped_on_ghosts = True
                    break
                start = time.perf_counter()
                state, ms = client.edit(**body)
                actions += 1
                fitted = state["fit"]["ok"]
                if fitted:
                    latencies.append((op, ms))
                    if op != "hide":  # (an H press is answered without a fit)
                        quick_cpu.append(state["fit"]["cpu_seconds"] * 1000.0)
                        server_cpu.append(client.server_cpu_ms)
                    if not state["refined"]:
                        landed = client.refined(state["revision"])
                        if landed is not None:
                            quick_off.append(ghosts_apart(state["fit"], landed["fit"]))
                            state = landed
                            refined_s.append(time.perf_counter() - start)
                marks = {n: tuple(uv) for n, uv in state["marks"].items()}
                full = live_fit.fit_marks(marks, session.image_size, session.prior, quick=False).fit \
                    if len(marks) >= live_fit.MIN_MARKS else None
                d3, d2 = ref.distances(full)
                rows.append({"action": actions, "op": op, "name": asked, "marks": len(marks), "latency_ms": ms if fitted else None,
                             "d3_mm": d3, "d2_px": d2, "same": ref.same(d3, d2),
                             "same_earlier_rule": ref.same_earlier_rule(d3, d2),
                             "settled": bool(state["settled"])})
                if args.verbose:
                    print(f"  {name} {actions:2d} {op:6s} {asked:28s} {len(marks):2d} marks  {ms:6.0f} ms  "
                          f"3D {d3:6.1f} mm  photo {d2:5.1f} px{'  same' if rows[-1]['same'] else ''}"
                          f"{'  settled' if state['settled'] else ''}", flush=True)
        finally:
            server.shutdown()
            server.server_close()
            session.close()
    same_at, same_at_earlier = (same_from(rows, key) for key in ("same", "same_earlier_rule"))
    settled = next((r for r in rows if r["settled"]), None)
    first_fit = next((r["action"] for r in rows if r["marks"] >= live_fit.MIN_MARKS), None)
    return {"photo": name, "hand": len(hand), "view_guess_deg": guess, "view_fit_deg": float(ref.fit.view.azimuth),
            "view_picked_deg": picked, "car_length_px": ref.length_px, "tau3_mm": ref.tau3, "tau2_px": ref.tau2,
            "same_at": same_at, "same_at_earlier_rule": same_at_earlier,
            "remarkings_passing": ref.remarkings_passing(), "score_bar": ref.bar,
            "first_same_at": next((r["action"] for r in rows if r["same"]), None),
            "settled_at": settled and settled["action"], "first_fit_at": first_fit,
            "settled_d3_mm": settled and settled["d3_mm"], "settled_d2_px": settled and settled["d2_px"],
            "actions_to_end": actions, "accepted": sum(r["op"] == "accept" for r in rows),
            "stopped_settled": bool(rows and rows[-1]["settled"]), "stopped_on_ghosts": stopped_on_ghosts,
            "same_when_stopped": bool(rows and rows[-1]["same"]),
            "hidden": sum(r["op"] == "hide" for r in rows), "dragged": sum(r["op"] == "drag" for r in rows),
            "user": args.user, "latency_ms": latencies, "quick_fit_cpu_ms": quick_cpu,
            "quick_off_full_px": quick_off, "refined_s": refined_s, "server_cpu_ms": server_cpu,
            "rows": rows}


def next_action(state: dict, hand: dict, accept_px: float, user: str,
                rng: np.random.Generator | None = None, notice: float = 0.0) -> tuple[str, str, dict]:
    """(op, keypoint, the edit's body): the simulated user's next action (module docstring).

    ``user`` "asked": the keypoint the page asks for: accept its ghost if within ``accept_px`` of
    the hand mark, else click the hand mark; H if the hand marks lack it. "ghosts": once the page
    draws ghosts, drag the ghost farthest from its hand mark there, while one is further than
    ``accept_px``; then stop (("stop", None, None): every ghost sits on its point). "ghosts-any":
    as "ghosts", but any of the ghosts further off than ``accept_px`` and at least ``notice``
    times as far off as the furthest, picked at random (``rng``)."""
    ghosts = state["fit"]["ghosts"] if state["fit"]["ok"] else {}
    if user in ("ghosts", "ghosts-any"):
        apart = {n: float(np.hypot(*np.subtract(g["uv"], hand[n]))) for n, g in ghosts.items()
                 if n in hand and n not in state["marks"]}
        off = {n: d for n, d in apart.items() if d > accept_px}
        if off:
            names = sorted(n for n in off if off[n] >= notice * max(off.values()))
            worst = max(off, key=off.get) if user == "ghosts" else names[int(rng.integers(len(names)))]
            return "drag", worst, {"op": "place", "name": worst, "uv": list(hand[worst])}
        if ghosts:
            return "stop", None, None
    asked = state["ask"][0]
    ghost = ghosts.get(asked)
    if asked not in hand:
        return "hide", asked, {"op": "hide", "name": asked}
    if ghost is not None and np.hypot(*np.subtract(ghost["uv"], hand[asked])) <= accept_px:
        return "accept", asked, {"op": "accept", "name": asked}
    return "click", asked, {"op": "place", "name": asked, "uv": list(hand[asked])}


def same_from(rows: list[dict], key: str) -> int | None:
    """The first action after which every row is the same (``rows[i][key]``) to the last one."""
    at = None
    for r in reversed(rows):
        if not r[key]:
            break
        at = r["action"]
    return at


def ghosts_apart(quick: dict, full: dict) -> float:
    """Median distance (px) between the quick fit's and the full fit's predicted keypoints: the
    ghosts and the reprojected marks both draw."""
    def predicted(fit: dict) -> dict:
        return {**{n: g["uv"] for n, g in fit["ghosts"].items()}, **{n: m["reprojected"] for n, m in fit["marks"].items()}}

    a, b = predicted(quick), predicted(full)
    common = [n for n in a if n in b]
    return float(np.median([np.hypot(*np.subtract(a[n], b[n])) for n in common])) if common else float("nan")


def brisk_latencies(clicks: int) -> list[float]:
    """The example's marks clicked in the page's order as fast as the answers come."""
    from carbody.annotate.server import AnnotationServer
    from carbody.annotate.session import AnnotationSession
    from carbody.fit import read_keypoints

    hand = read_keypoints(REPO / "examples" / "car_keypoints.json").points
    with tempfile.TemporaryDirectory() as tmp:
        session = AnnotationSession(REPO / "examples" / "car.png", output=Path(tmp) / "marks.json")
        session.wait_started(120)
        server = AnnotationServer(session)
        server.serve_in_thread()
        client = Client(server)
        out = []
        try:
            state = client.state()
            for _ in range(clicks):
                if not state["ask"]:
                    break
                name = state["ask"][0]
                state, ms = client.edit(op="place", name=name, uv=list(hand[name]))
                if state["fit"]["ok"]:
                    out.append(ms)
        finally:
            server.shutdown()
            server.server_close()
            session.close()
    return out


def size_and_prior(image: Path) -> tuple[tuple[int, int], object]:
    """(the photo's (width, height) px, the view prior the page's fits have: the classifier's)."""
    from carbody.annotate.session import AnnotationSession

    with tempfile.TemporaryDirectory() as tmp:
        session = AnnotationSession(image, output=Path(tmp) / "marks.json", full_fits=False, warm_up=False)
        session.wait_started(120)  # the classifier's prior, as the guided session has it
        size, prior = session.image_size, session.prior
        session.close()
    return size, prior


def oracle(name: str, image: Path, marks_file: Path, args) -> dict:
    """The fewest hand marks a greedy order needs to reach the hand fit (module docstring)."""
    from carbody.annotate import live_fit
    from carbody.fit import read_keypoints

    hand = read_keypoints(marks_file).points
    size, prior = size_and_prior(image)
    from carbody.view.predict import read_image

    photo = read_image(image) if args.with_wheels or args.with_outline else None
    ref = Reference(hand, size, prior, args.accept, args.draws, photo=photo, outline=args.with_outline)
    names = list(hand)
    uv = np.array([hand[n] for n in names])
    order = [names[int(np.argmax(np.linalg.norm(uv - uv.mean(axis=0), axis=1)))]]
    while len(order) < live_fit.MIN_MARKS:
        near = np.min(np.linalg.norm(uv[:, None] - np.array([hand[n] for n in order])[None], axis=2), axis=1)
        order.append(names[int(np.argmax(near))])

    def distances(chosen):
        return ref.distances(ref.fit_marks({n: hand[n] for n in chosen}))

    d3, d2 = distances(order)
    while not ref.same(d3, d2) and len(order) < len(names):
        tried = [(distances(order + [n]), n) for n in names if n not in order]
        (d3, d2), best = min(tried, key=lambda t: ref.score(*t[0]))
        order.append(best)
        if args.verbose:
            print(f"  oracle {name} {len(order):2d} {best:28s} 3D {d3:6.1f} mm  photo {d2:5.1f} px", flush=True)
    return {"photo": name, "hand": len(hand), "marks": len(order), "order": order, "with_wheels": photo is not None,
            "with_outline": args.with_outline,
            "same": ref.same(d3, d2), "tau3_mm": ref.tau3, "tau2_px": ref.tau2}


def detected(name: str, image: Path, marks_file: Path, args) -> list[dict]:
    """How many actions a key that places keypoints where a detector puts them would leave (module
    docstring, ``--detector``): one row per detector."""
    from carbody.fit import read_keypoints

    hand = read_keypoints(marks_file).points
    size, prior = size_and_prior(image)
    ref = Reference(hand, size, prior, args.accept, args.draws)
    accept_px = args.accept * ref.length_px
    detectors = [(f"hand marks moved {e:g} % of the car's length (median)", e) for e in args.detector]
    if args.detector_net:
        detectors.append((f"the network {args.detector_net.name}"
                          + (", the hand-marked names" if args.detector_hand_names else
                             f", peaks of {args.detector_peak:g} or more"), None))
    rows = []
    for label, error in detectors:
        if error is None:
            found = network_detections(args.detector_net, image, hand,
                                       None if args.detector_hand_names else args.detector_peak)
        else:
            found = moved_marks(hand, error / 100.0 * ref.length_px, np.random.default_rng([args.seed, len(hand)]))
        steps = drags_to_the_hand_fit(found, hand, ref, accept_px)
        within = np.mean([n in found and np.hypot(*np.subtract(found[n], hand[n])) <= accept_px for n in hand])
        rows.append({"photo": name, "hand": len(hand), "detector": label, "within_click": float(within),
                     "placed": len(found), "placed_unmarked": len(set(found) - set(hand)),
                     "same_at": same_from(steps, "same"), "actions": len(steps), "steps": steps})
        if args.verbose:
            print(f"  detected {name} {label}: same at {rows[-1]['same_at']} of {len(hand)}", flush=True)
    return rows


def moved_marks(hand: dict, median_px: float, rng: np.random.Generator) -> dict:
    """``hand`` {name: (u, v)} each moved at random, isotropically, ``median_px`` at the median (a
    2D Gaussian's median radius is 1.1774 σ)."""
    sigma = median_px / np.sqrt(2.0 * np.log(2.0))
    return {n: tuple(np.add(uv, rng.normal(0.0, sigma, 2))) for n, uv in hand.items()}


def drags_to_the_hand_fit(found: dict, hand: dict, ref, accept_px: float) -> list[dict]:
    """The detector key's user (module docstring, ``--detector``): the marks ``found`` placed by one
    key; then, while one is more than ``accept_px`` off, the furthest off is put right: a mark
    (or the ghost of a hand-marked keypoint the key left out) dragged onto its hand mark, or a
    mark the hand marks lack removed when it lies off the hand fit's keypoint. One row per
    action: whether the full fit (``ref.fit_marks``) is then the same as the hand fit
    (``ref.same`` of ``ref.distances``)."""
    marks, steps = dict(found), []
    hand_fit = ref.projected(None)
    while True:
        fit = ref.fit_marks(marks)
        d3, d2 = ref.distances(fit)
        steps.append({"action": 1 + len(steps), "same": ref.same(d3, d2), "d3_mm": d3, "d2_px": d2})
        ghosts = ref.projected(fit) if fit is not None else {}
        off = {n: float(np.hypot(*np.subtract(marks[n] if n in marks else ghosts.get(n, (np.inf, np.inf)), uv)))
               for n, uv in hand.items()}
        off |= {n: float(np.hypot(*np.subtract(marks[n], hand_fit[n]))) for n in marks if n not in hand}
        worst = max(off, key=off.get)
        if off[worst] <= accept_px:
            return steps
        if worst in hand:
            marks[worst] = hand[worst]  # one drag (or click) onto the point
        else:
            del marks[worst]            # one Backspace


def network_detections(weights: Path, image: Path, hand: dict, peak: float | None) -> dict:
    """{name: (u, v)}: every keypoint ``benchmarks/probe_keypoints.py``'s network with ``weights``
    finds with a peak of at least ``peak`` (None: every hand-marked keypoint, however low its
    peak), reading the hand marks' box (taken lower, as that probe does) and the photo mirrored
    too."""
    import cv2

    sys.path.insert(0, str(REPO / "benchmarks"))
    import probe_keypoints
    import probe_tyres

    rgb = cv2.imread(str(image))[..., ::-1].copy()
    box = probe_tyres.points_box(list(hand.values()))
    uv, height = probe_keypoints.detect(probe_keypoints.trained_network(weights), rgb, box, flip=True)
    return {n: tuple(uv[k]) for k, n in enumerate(probe_keypoints.keypoint_names())
            if (n in hand if peak is None else height[k] >= peak)}


#: The quick policies ``--quick-vs-full`` compares: the page's, and the one before commit 5db2425.
QUICK_POLICIES = ("the page's (three views ranked, the coarse noise kept)",
                  "before 5db2425 (six views ranked, the noise read again)")


def quick_against_full(cases: list[tuple[str, Path, Path]], every: int = 3) -> list[dict]:
    """One row per quick policy (``QUICK_POLICIES``): the quick fit against the full fit of the
    same marks (module docstring, "Quick against full"), over ``cases`` ((name, image, marks))."""
    from dataclasses import replace

    from PIL import Image

    from carbody.annotate import live_fit
    from carbody.fit import ViewPrior, read_keypoints
    from carbody.library import default_library

    library = default_library()
    page = live_fit.quick_policy
    policies = (page, lambda previous: replace(page(previous), ranked_candidates=6, fine_noise=True))
    rows = [{"policy": label, "fits": 0, "cpu_ms": [], "off_pct": [], "views_off": 0} for label in QUICK_POLICIES]
    full_fits: dict[tuple[str, int], object] = {}
    for row, policy in zip(rows, policies):
        live_fit.quick_policy = policy
        try:
            for name, image, marks_file in cases:
                hand = read_keypoints(marks_file).points
                names, size, last = list(hand), Image.open(image).size, None
                for count in range(live_fit.MIN_MARKS, len(names) + 1):
                    marks = {n: hand[n] for n in names[:count]}
                    quick = live_fit.fit_marks(marks, size, None if last is None else ViewPrior.told(last), last,
                                               quick=True, library=library)
                    if quick.fit is None:
                        continue
                    last = quick.fit.view
                    if count % every and count != len(names):
                        continue
                    if (name, count) not in full_fits:
                        full_fits[name, count] = live_fit.fit_marks(marks, size, None, quick=False, library=library).fit
                    full = full_fits[name, count]
                    at_quick, at_full = live_fit.keypoint_positions(quick.fit), live_fit.keypoint_positions(full)
                    apart = np.linalg.norm(quick.fit.project_points(np.array([at_quick[n] for n in at_full]))
                                           - full.project_points(np.array([at_full[n] for n in at_full])), axis=1)
                    length = float(np.ptp(np.array(live_fit.projected_wireframe(full)).reshape(-1, 2)[:, 0]))
                    row["fits"] += 1
                    row["cpu_ms"].append(1000.0 * quick.cpu_seconds)
                    row["off_pct"].append(100.0 * float(np.median(apart)) / length)
                    row["views_off"] += angular(quick.fit.view.azimuth, full.view.azimuth) > 30.0
        finally:
            live_fit.quick_policy = page
    return rows


#: Bins of the facing cosine (:func:`facing_rates`).
FACING_BINS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.7, 1.0)


def facing_rates(data: Path) -> list[dict]:
    """On every real photo in ``data``: the keypoints the full fit of its hand marks shows on the
    photo, binned by how squarely they face the camera, and the share its annotator marked."""
    from carbody.annotate import guide, live_fit
    from carbody.fit import read_keypoints

    rows = []
    for marks_file in sorted((data / "keypoints").glob("cps_*.json")):
        ann = read_keypoints(marks_file)
        fit = live_fit.fit_marks(ann.points, ann.image_size, None, quick=False).fit
        if fit is None:
            continue
        points = live_fit.keypoint_positions(fit)
        where = dict(zip(points, fit.project_points(np.array(list(points.values())))))
        cos = guide.facing_cosines(fit.view, fit.wireframe.control_points / fit.mm_per_unit)
        w, h = ann.image_size
        for name in live_fit.visible_names(fit):
            u, v = where[name]
            if 0 <= u <= w and 0 <= v <= h:
                rows.append({"photo": marks_file.stem, "name": name, "cos": cos[name], "marked": name in ann.points})
    out = []
    for low, high in zip(FACING_BINS[:-1], FACING_BINS[1:]):
        group = [r for r in rows if low <= r["cos"] < high or (high == FACING_BINS[-1] and r["cos"] >= high)]
        if group:
            out.append({"cos": [low, high], "shown": len(group), "marked": float(np.mean([r["marked"] for r in group]))})
    return out


def percentiles(values: list[float]) -> str:
    if not values:
        return "—"
    v = np.array(values)
    return (f"median {np.median(v):.0f}, p90 {np.percentile(v, 90):.0f}, max {v.max():.0f} ms; "
            f"{np.mean(v <= LATENCY_TARGET_MS) * 100:.0f} % within {LATENCY_TARGET_MS:.0f} ms (n = {len(v)})")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--photos", nargs="*", default=list(DEFAULT_PHOTOS), help="real photos by name (cps_*)")
    parser.add_argument("--data", type=Path, default=REPO.parent / "shared" / "realphotos",
                        help="the real photos' folder (images/, keypoints/)")
    parser.add_argument("--draws", type=int, default=12, help="re-markings for the same-fit tolerance")
    parser.add_argument("--accept", type=float, default=0.01,
                        help="a careful click's error, as a fraction of the car's length in the photo")
    parser.add_argument("--brisk", type=int, default=20, help="clicks of the brisk latency run (0: none)")
    parser.add_argument("--json", type=Path, default=None, help="write every figure here")
    parser.add_argument("--verbose", "-v", action="store_true", help="print every action")
    parser.add_argument("--oracle", action="store_true", help="also the fewest hand marks a greedy order needs")
    parser.add_argument("--with-wheels", action="store_true",
                        help="the oracle's fits given the photo too: the wheels' hubs found in it join the marks")
    parser.add_argument("--with-outline", action="store_true",
                        help="the oracle's fits given the photo's wheels and the car's outline in it too")
    parser.add_argument("--facing", action="store_true",
                        help="also the annotators' share of marked keypoints by how squarely they face the camera")
    parser.add_argument("--no-guided", action="store_true", help="skip the guided sessions and the latencies")
    parser.add_argument("--quick-vs-full", action="store_true",
                        help="also the quick fit against the full fit on every real photo, both quick policies")
    parser.add_argument("--every", type=int, default=3, help="--quick-vs-full fits every this many marks")
    parser.add_argument("--user", choices=("asked", "ghosts", "ghosts-any"), default="asked",
                        help="the simulated user: marks what the page asks ('asked'), or first drags "
                             "the ghost farthest off its point while one is off by more than a click ('ghosts'), "
                             "or any ghost off by more than a click, at random ('ghosts-any')")
    parser.add_argument("--seed", type=int, default=0, help="the 'ghosts-any' user's random picks")
    parser.add_argument("--notice", type=float, default=0.0,
                        help="the 'ghosts-any' user picks among the ghosts at least this share as far off as "
                             "the furthest (0: any ghost off by more than a click)")
    parser.add_argument("--detector", type=float, nargs="*", default=[], metavar="PCT",
                        help="also a key placing every hand-marked keypoint as a detector would: the hand marks "
                             "moved by PCT %% of the car's length at the median (each value given)")
    parser.add_argument("--detector-net", type=Path, default=None, metavar="W.pt",
                        help="... and as benchmarks/probe_keypoints.py's network with these weights places them")
    parser.add_argument("--detector-peak", type=float, default=0.3,
                        help="the network's key places the keypoints whose heat map peaks at least this high")
    parser.add_argument("--detector-hand-names", action="store_true",
                        help="the network's key places every hand-marked keypoint and no other, as if it knew "
                             "what the annotator would mark")
    parser.add_argument("--to-the-end", action="store_true",
                        help="the simulated user goes on past the page's 'settled' until nothing is asked")
    args = parser.parse_args(argv)

    load = os.getloadavg()
    cases = [("example", REPO / "examples" / "car.png", REPO / "examples" / "car_keypoints.json")]
    if args.photos and not args.data.is_dir():
        print(f"note: {args.data} is not here: the real photos are skipped")
    else:
        for name in args.photos:
            image, marks = args.data / "images" / f"{name}.jpg", args.data / "keypoints" / f"{name}.json"
            if image.is_file() and marks.is_file():
                cases.append((name, image, marks))
            else:
                print(f"note: {name} is not in {args.data}: skipped")
    results, oracles, facing = [], [], []
    for name, image, marks in cases if not args.no_guided else []:
        started = time.perf_counter()
        results.append(guided_session(name, image, marks, args))
        results[-1]["wall_s"] = time.perf_counter() - started
    brisk = brisk_latencies(args.brisk) if args.brisk and not args.no_guided else []
    if args.oracle:
        oracles = [oracle(name, image, marks, args) for name, image, marks in cases]
    detections = [row for name, image, marks in cases for row in detected(name, image, marks, args)] \
        if args.detector or args.detector_net else []
    if args.facing and args.data.is_dir():
        facing = facing_rates(args.data)
    quick_rows = []
    if args.quick_vs_full:
        every_photo = cases[:1] + ([(p.stem, args.data / "images" / f"{p.stem}.jpg", p)
                                    for p in sorted((args.data / "keypoints").glob("*.json"))]
                                   if args.data.is_dir() else [])
        quick_rows = quick_against_full(every_photo, args.every)
    load_end = os.getloadavg()

    print(f"\nmachine: {os.cpu_count()} cores; load average {load[0]:.1f} at the start, {load_end[0]:.1f} at the end")
    if results:
        print(f"simulated user: {args.user}" + (f", seed {args.seed}, notice {args.notice}" if args.user == "ghosts-any" else ""))
        print("\n| photo | hand marks | view guessed → fitted (picked) | first fit at | same fit at | earlier rule "
              "| first same | settled at (3D mm / photo px there) | actions in all (accepted, hidden, dragged) | the same fit then "
              "| τ3 mm / τ2 px | re-markings the same, score / earlier rule |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in results:
        same, earlier = ("never" if at is None else f"{at} ({at / r['hand']:.0%})"
                         for at in (r["same_at"], r["same_at_earlier_rule"]))
        by_score, by_rule, draws = r["remarkings_passing"]
        settled = "never" if r["settled_at"] is None else \
            f"{r['settled_at']} ({r['settled_d3_mm']:.0f} / {r['settled_d2_px']:.1f})"
        picked = "" if r["view_picked_deg"] is None else f" (picked {r['view_picked_deg']:.0f}°)"
        print(f"| {r['photo']} | {r['hand']} | {r['view_guess_deg']:.0f}° → {r['view_fit_deg']:.0f}°{picked} | "
              f"{r['first_fit_at']} | {same} | {earlier} | {r['first_same_at']} | {settled} | "
              f"{r['actions_to_end']} ({r['accepted']}, {r['hidden']}, {r['dragged']})"
              f"{' settled' if r['stopped_settled'] else ' no ghost off' if r.get('stopped_on_ghosts') else ''} | "
              f"{'yes' if r['same_when_stopped'] else 'no'} | {r['tau3_mm']:.0f} / {r['tau2_px']:.1f} | "
              f"{by_score} / {by_rule} of {draws} |")
    if oracles:
        wheels = (" (the photo's wheels and outline fitted too)" if args.with_outline else
                  " (the photo's wheels fitted too)" if args.with_wheels else "")
        print(f"\n| photo | hand marks | the greedy order's marks to the same fit{wheels} | τ3 mm / τ2 px |")
        print("|---|---|---|---|")
        for o in oracles:
            marks = f"{o['marks']} ({o['marks'] / o['hand']:.0%})" if o["same"] else f"not within {o['marks']}"
            print(f"| {o['photo']} | {o['hand']} | {marks} | {o['tau3_mm']:.0f} / {o['tau2_px']:.1f} |")
    if detections:
        print("\n| photo | hand marks | detector | marks placed (the hand marks lack) | hand marks placed within a click "
              "| same fit at (actions: the key, then drags and removals) | actions in all |")
        print("|---|---|---|---|---|---|---|")
        for d in detections:
            same = "never" if d["same_at"] is None else f"{d['same_at']} ({d['same_at'] / d['hand']:.0%})"
            print(f"| {d['photo']} | {d['hand']} | {d['detector']} | {d['placed']} ({d['placed_unmarked']}) | "
                  f"{d['within_click']:.0%} | {same} | {d['actions']} |")
    if facing:
        print("\n| facing cosine | keypoints shown on the photo | share marked by the annotator |")
        print("|---|---|---|")
        for f in facing:
            print(f"| {f['cos'][0]:.1f}–{f['cos'][1]:.1f} | {f['shown']} | {f['marked']:.0%} |")
    if quick_rows:
        print("\n| quick policy | fits | processor time, median / p90 ms | keypoints off the full fit's, median / p90 "
              "% of the car's length | views more than 30° off the full fit's |")
        print("|---|---|---|---|---|")
        for q in quick_rows:
            print(f"| {q['policy']} | {q['fits']} | {np.median(q['cpu_ms']):.0f} / {np.percentile(q['cpu_ms'], 90):.0f} | "
                  f"{np.median(q['off_pct']):.2f} / {np.percentile(q['off_pct'], 90):.2f} | {q['views_off']} |")
    if not results:
        if args.json:
            args.json.write_text(json.dumps({"load_start": load, "load_end": load_end, "oracle": oracles,
                                             "detected": detections, "facing": facing,
                                             "quick_vs_full": quick_rows}, indent=1))
        return 0
    paused = [ms for r in results for op, ms in r["latency_ms"] if op != "hide"]
    hides = [ms for r in results for op, ms in r["latency_ms"] if op == "hide"]
    refined = [s for r in results for s in r["refined_s"]]
    print(f"\nlatency, paused clicks and accepts (a quick fit): {percentiles(paused)}")
    print(f"latency, H presses (no fit): {percentiles(hides)}")
    print(f"latency, brisk clicks:  {percentiles(brisk)}")
    cpu = [ms for r in results for ms in r["quick_fit_cpu_ms"]]
    print(f"the quick fit's processor time, paused clicks: {percentiles(cpu)}")
    server = [ms for r in results for ms in r["server_cpu_ms"]]
    print(f"the server's processor time per click (the fit, the state, the JSON): {percentiles(server)}")
    if refined:
        print(f"full fit landed after: median {np.median(refined):.2f} s, max {max(refined):.2f} s")
    off = [v for r in results for v in r["quick_off_full_px"] if np.isfinite(v)]
    if off:
        print(f"the quick fit's keypoints off the full fit's: median {np.median(off):.1f} px, "
              f"p90 {np.percentile(off, 90):.1f} px (n = {len(off)})")
    if args.json:
        args.json.write_text(json.dumps({"load_start": load, "load_end": load_end, "cases": results,
                                         "brisk_latency_ms": brisk, "oracle": oracles, "detected": detections,
                                         "facing": facing,
                                         "quick_vs_full": quick_rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
