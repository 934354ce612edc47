"""The fit's thresholds in one place: what each one protects against.

:class:`FitPolicy` is a frozen dataclass; :class:`carbody.fit.FitOptions` carries one (the
default :data:`FIT_POLICY`), so a test or a benchmark changes a threshold by passing another
policy, never by patching a module. Units: degrees, nats (−log likelihood), fractions of the
marks' RMS spread about their centre (``keypoint_spread``: ≈ 300 px for a car 900 px wide).
:mod:`carbody.tolerances` holds the geometric tolerances and units; this file holds decisions.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FitPolicy:
    """Thresholds of the fit (:func:`carbody.fit.fit_wireframe`), each with what it protects
    against."""

    # ---- the view search (carbody.fit.search)

    #: Azimuths scanned all round the car, this far apart: the 24 classes of both sides. Finer
    #: costs a solve per view per elevation; the local refinement closes the gap.
    scan_azimuth_step_deg: float = 15.0

    #: Elevations scanned at every azimuth: photos are taken from a person's height (0–20°),
    #: some from above. Near a side view a wrong elevation passes for a wrong azimuth, so one
    #: elevation alone can settle in the wrong valley.
    scan_elevations_deg: tuple[float, ...] = (-10.0, 0.0, 10.0, 20.0, 35.0)

    #: Perspectives scanned when the camera's distance is to be found: orthographic and
    #: 2.5 wheelbases (≈ 7 m, a typical photo), as wheelbases per distance (ρ = 1000 / D).
    #: A photo from afar looks orthographic, and the two hypotheses' best angles can differ.
    scan_perspectives: tuple[float, ...] = (0.0, 0.4)

    #: The best this many hypotheses of the scan, this far apart in azimuth or elevation, are
    #: refined: the evidence is not convex round the car (the other end, the mirror side, a
    #: level view's width/azimuth trade) and the scan's cheap solve may rank close ones wrong.
    refined_candidates: int = 3
    candidate_separation_deg: float = 20.0

    #: … chosen among the scan's best this many (as far apart), ranked by the full solve at the
    #: marks' noise each reads at its own view: the cheap solve is the library's span alone,
    #: and a real car, no library car, can fit a few marks best there at the wrong view.
    ranked_candidates: int = 6

    #: Each candidate's local refinement: at most this many cheap solves, then the best one
    #: polished with the full shape model to this many solves and this precision (degrees).
    coarse_evaluations: int = 40
    polish_evaluations: int = 180
    polish_tolerance_deg: float = 0.1

    #: The refined elevation stays in this range (degrees): beyond it no photo of a car is taken,
    #: and a car seen steeply from above can be bent to fit most marks.
    elevation_range_deg: tuple[float, float] = (-20.0, 60.0)

    #: A told azimuth counts as a von Mises prior of this standard deviation (degrees): strong
    #: enough to choose between views the marks fit alike, far too weak to keep a view the
    #: marks contradict (a view 180° off costs ≈ 7 nats; a wrong end thousands).
    view_prior_sd_deg: float = 30.0

    #: The elevation prior: a Gaussian of this standard deviation (degrees) around the told
    #: elevation (0° unless told): photos are taken from near a person's height.
    elevation_prior_sd_deg: float = 20.0

    #: The roll prior: a Gaussian of this standard deviation (degrees) around the told roll (0°
    #: unless told): a photo taken by hand is seldom level to within a degree or two. The fit
    #: frees the roll, within ``roll_range_deg`` of the told one, only where the marks pay for
    #: it (:func:`carbody.fit.search.with_roll`; 0: the roll kept as told).
    roll_prior_sd_deg: float = 2.0
    roll_range_deg: float = 15.0

    #: A classifier's probabilities are floored at this share of a uniform prior before they
    #: count: a confident but wrong classifier must not veto the view the marks fit.
    classifier_floor: float = 0.05

    # ---- what the marks' names say (carbody.fit.visibility.FacingTable)

    #: A marked keypoint counts as hidden from a view only when no region at it faces a camera
    #: within this many degrees of that view: the library's mean car is not the photo's car,
    #: and marks on the silhouette are clicked from views where they only just show.
    visibility_margin_deg: float = 15.0

    # ---- the robust estimate of the marks (carbody.fit.robust)

    #: Prior probability that a mark is misplaced (a click on the wrong feature, a name slipped):
    #: a mark is left out when its density under the fit of the others is below this share of
    #: a click anywhere on the photo (for 2 px marks ≈ 5 standard deviations off).
    outlier_probability: float = 0.05

    #: … and only when the others predict it further than this fraction of the marks' spread
    #: (≈ 9 px for a car 900 px wide): a car unlike every template misses its genuine marks by
    #: a few pixels, many of its own noise levels, and those marks carry its shape.
    outlier_floor_spread: float = 0.03

    #: … and only when its own residual stands out, this many times the marks' median: a point
    #: the car can bend to (the library and its local field reach it) is a feature of this car —
    #: a pickup's bed corner among saloons — not a misplaced click, which no car follows.
    outlier_residual_ratio: float = 4.0

    #: At most this fraction of the marks is left out, and at least ``min_kept`` stay: the
    #: estimate explains the marks by the car, not the car by a handful of them. A view that
    #: cannot see more than this fraction of them is not the photo's (the names say so): a
    #: close photo fitted as if from afar misses every mark by pixels, and a view seeing only a
    #: few of them would explain those few better.
    max_rejected_fraction: float = 0.25
    min_kept: int = 6

    #: The marks' noise is read off them (the factor of the best evidence at the view found) among
    #: these multiples of λ's standard deviation (≈ 1 % of the marks' spread): a person's clicks
    #: on a real photo are 1–1.5 % of the car's length off, several times λ's, and at λ's noise
    #: the fit bends the car far outside the library to follow them.
    noise_factors: tuple[float, ...] = (1.0, 1.5, 2.2, 3.3, 5.0)

    #: … and the joint field's amplitude (the library's local freedom: features moved along the
    #: car) among these multiples of JOINT_FIELD_AMPLITUDE: a car unlike every template (a pickup
    #: among saloons) misses its marks in a pattern the field follows, which is no click noise.
    field_scales: tuple[float, ...] = (1.0, 2.0, 3.0)

    #: The noise is read once more where the chosen view settles, on the full grid (False: on
    #: every other value of each list, as the candidates are ranked; the page's quick fit,
    #: which the full fit replaces within a second).
    fine_noise: bool = True

    #: The scan's hypotheses leave out at most this many marks (a whole solve each): enough that
    #: one wild mark does not push the right view out of the best few.
    scan_rejections: int = 1

    #: Discrete hypotheses on the names of marks left out (a left/right pair exchanged, a mark
    #: clicked under its twin's name; on a poor fit every pair marked whole), each scored at the
    #: view found, the best this many refined, one kept when it explains the marks better by this
    #: many nats: a name is changed only when the marks say so clearly.
    twin_hypotheses: int = 4
    twin_margin_nats: float = 10.0

    #: A kept mark is named suspect when its residual exceeds this many times the median and
    #: this fraction of the marks' spread (a mark the car cannot follow, not left out).
    suspect_ratio: float = 4.0
    suspect_spread: float = 0.05

    #: A mark left out "looks like" another keypoint when the fitted car puts that one within
    #: this fraction of the marks' spread of it: a click meant for another name.
    looks_like_spread: float = 0.02

    # ---- how well the fit explains the marks (carbody.fit.diagnostics)

    #: −log evidence per marked coordinate above which no car near the view found fits the marks
    #: (``fits_poorly``): set between the leave-one-out cars' fits at their own views (≤ 6.1 with
    #: 5 px of noise) and at their other end (≥ 34.9); docs/fit_accuracy.md.
    poor_fit_evidence: float = 10.0

    #: The fitted car misses the marks (``misses_marks``) when its mean residual exceeds this
    #: fraction of their spread, whatever the method: a car no better than a guess.
    misses_marks_spread: float = 0.05

    #: A full solve at a pinhole view is no fit when its marks' points, projected through the
    #: real camera, miss the marks by more than its linearised camera said, by over this
    #: fraction of their spread (:meth:`~carbody.fit.hypothesis.Scorer.camera_holds`; a car
    #: bent toward the camera on a re-marked front view: 3.7; the real photos' own fits and the
    #: renders' came out the same with the check, docs/fit_accuracy.md).
    linearised_camera_spread: float = 0.25

    #: A fit is refused (``contradicts``: exit 2 unless forced) only where the marks contradict
    #: each other, far past both notes: −log evidence per coordinate above this (the
    #: leave-one-out cars' other end scores ≥ 34.9, their own view ≤ 6.1 at 5 px of noise) ...
    refuse_evidence: float = 25.0
    #: ... or a mean residual above this fraction of the marks' spread (three times the
    #: ``misses_marks`` note's: a car the library lacks misses its marks by a few per cent, a
    #: contradiction by tens).
    refuse_misses_spread: float = 0.15

    # ---- the camera (carbody.fit.fit_camera)

    #: Told the orthographic camera, a camera close by "fits far better" when its mean residual
    #: is at most this fraction of the orthographic one, or its −log evidence per coordinate is
    #: lower by more than ``closer_camera_evidence`` (a photo from a few metres fitted as if from
    #: afar comes out distorted; docs/fit_accuracy.md: at most 0.32 on pictures from afar).
    closer_camera_gain: float = 0.6
    closer_camera_evidence: float = 1.0

    #: Refits with the camera turned toward an off-centre car (each from the previous one's
    #: aim), until the direction to the car's centre moves less than this (degrees: left over,
    #: such a tilt draws one end of a car spanning 30° of the photo ≈ 0.2 % larger).
    turn_passes: int = 4
    turn_tolerance_deg: float = 0.25

    #: With the focal length unknown and the distance found, the turn tries focal lengths up to
    #: this factor either side of the settled turn's, on a log grid of this many, then to this
    #: precision in log f: an oblique image plane passes for a nearer camera, whose own focal
    #: length then turns the camera wrongly.
    focal_search_range: float = 3.0
    focal_search_grid: int = 7
    focal_search_tolerance: float = 0.05

    #: A focal length under this fraction of the photo's diagonal is no camera's (10 mm in 35 mm
    #: terms, wider than the widest phone lens): a fit bent to the wrong end drifts there.
    min_focal_diagonal: float = 10.0 / 43.3

    #: A car's size read from a told camera distance and the fit's perspective is taken when it
    #: lies within this factor of the library's wheelbases (beyond: too little perspective); else
    #: the told distance is read at the fitted car's own wheelbase, in at most
    #: ``distance_passes`` fits until the two agree to ``distance_agreement``.
    perspective_size_range: float = 1.5
    distance_passes: int = 3
    distance_agreement: float = 0.005

    # ---- the car's size when no wheelbase or distance is told (carbody.fit.size)

    #: The least uncertainty of each fitted proportion (length, width, height in wheelbases),
    #: a fraction: the published figures' ±2 % and the keypoints standing in for the extents'
    #: spread, which the fit's posterior does not know.
    size_proportion_floor: float = 0.03

    #: The size moves the fitted car along its trade with the image scale, which the marks
    #: cannot tell (:func:`carbody.fit.solve.along_scale`). A move that raises the marks' mean
    #: residual by more than ``size_move_misfit`` × their noise (√λ × their spread, px) has
    #: left the range where that trade is linear (a close camera, marks no car fits): it is
    #: halved, at most ``size_move_halvings`` times, and else not made.
    size_move_misfit: float = 0.5
    size_move_halvings: int = 3

    #: The fitted car's length in wheelbases is moved to the one the published cars give it
    #: (:func:`carbody.fit.single_view._lengthened`), as far as the marks let it: an end they
    #: do not show is then the table's guess, not the library mix's.
    size_length_move: bool = True

    # ---- the car's outline in the photo (carbody.fit.outline)

    #: The segmentation works on the photo scaled down to this many pixels on its longer side:
    #: GrabCut's cost grows with the pixels, and a car's outline needs no more (≈ 0.2 s).
    outline_working_px: int = 480
    outline_iterations: int = 4

    #: GrabCut's seeds, as factors on the marks' convex hull about its centre: surely car inside
    #: ``outline_sure_shrink`` (the marks lie on the body), probably car inside
    #: ``outline_probable_growth`` (bumpers, roof and wheels stand past the marks), probably
    #: background inside ``outline_background_growth``, background beyond.
    outline_sure_shrink: float = 0.7
    outline_probable_growth: float = 1.15
    outline_background_growth: float = 1.4

    #: A mask is trusted when its area is within this range of the marks' hull's (the car
    #: encloses its marks and not much more) and it runs along fewer than three sides of the
    #: photo for more than this fraction of each (else it took the background).
    outline_hull_ratio: tuple[float, float] = (0.9, 2.2)
    outline_frame_fraction: float = 0.5

    #: Points sampled inside each curve (its ends are junctions, often marks themselves); a point
    #: is on the projected body's outline within this many pixels.
    outline_samples_per_curve: int = 6
    outline_on_px: float = 1.5

    #: Outline points whose outward normal points further down than this (its image v component;
    #: 0.5: 30° below sideways) are not used: the lower outline is tyres, shadow and ground.
    outline_max_downward: float = 0.5

    #: A point is matched to the mask's edge along its normal within this fraction of the marks'
    #: spread (≈ 15 px for a car 900 px wide): further is another edge (a shadow, a kerb, the car
    #: behind), not this car's outline where the marks put it.
    outline_search_spread: float = 0.05

    #: The matches' noise standard deviation as a multiple of the marks' (read off the marks):
    #: a segmentation's edge is less sure than a person's click, and neighbouring matches share
    #: their errors (a shadow, a reflection) so they count less than independent marks.
    outline_noise_ratio: float = 3.0

    #: Match–solve rounds at the view found, and the fewest matches the outline is used with.
    outline_passes: int = 3
    outline_min_points: int = 8

    # ---- the wheels in the photo (carbody.fit.wheels)

    #: A wheel is looked for when the camera sees its outer face at least this much (the cosine
    #: between the face's normal and the way to the camera; 0.3: 17° off edge-on), a front
    #: wheel turned any way up to ``wheel_max_steer_deg``: nearer edge-on the tyre's tread and
    #: the body hide the hub, and the view's error stretches the warped wheel most.
    wheel_min_facing: float = 0.3

    #: … and when its tyre (this share of the arch's radius) is at least this many photo pixels
    #: in radius: smaller, its rim is a few pixels and any blob is a circle.
    wheel_tyre_share: float = 0.85
    wheel_min_radius_px: float = 12.0

    #: The hub is looked for within this many arch radii of where the fit puts it (the arch
    #: clearance and the view's error move it by less), on circles of these radii (arch radii:
    #: the rim's edge and the spokes' arcs inside, the tyre's outline out to the arch).
    wheel_window: float = 1.0
    wheel_radii: tuple[float, float] = (0.3, 1.05)

    #: Stretches of the warped patch along the car that are tried: the view found is a few
    #: degrees off, which stretches the wheel's circle into an ellipse (most near edge-on: at
    #: 20° off it, 5° of azimuth stretch it by a quarter).
    wheel_aspects: tuple[float, ...] = (0.62, 0.7, 0.79, 0.89, 1.0, 1.12, 1.26, 1.41)

    #: A parked car's front wheels are often turned: up to this many degrees either way
    #: (:func:`carbody.fit.wheels.wheel_distortions`); the stretches tried lie this factor apart.
    wheel_max_steer_deg: float = 20.0
    wheel_aspect_step: float = 1.12

    #: At least this share of the warped patch must lie on the photo (else the wheel is cut off).
    wheel_min_inside: float = 0.5

    #: One circle adds the share of its circumference that edges support less the floor, and
    #: at most the cap less the floor, to a centre's score: a hub is several concentric
    #: circles, not one crisp round thing, nor the few pixels that spokes' and panels'
    #: straight edges give every circle.
    wheel_circle_floor: float = 0.25
    wheel_circle_cap: float = 0.75

    #: A circle's support is counted in this many equal sectors round it, from edges whose
    #: gradient lies within acos(``wheel_alignment``) of its radius; the rough Hough centres'
    #: best ``wheel_candidates`` are scored so.
    wheel_sectors: int = 24
    wheel_alignment: float = 0.9
    wheel_candidates: int = 8

    #: A hub is found when its score is at least ``wheel_min_score`` (a circle whole all round
    #: counts about 1.5: more than one such circle). The centres more than ``wheel_separation``
    #: arch radii from it and from each other that score within ``wheel_min_margin`` of it are
    #: its rivals, carried into the fit with it, which weighs each by how well the car fits it.
    #: More rivals than ``wheel_rivals``: clutter or a body panel, which score alike everywhere;
    #: no hub.
    wheel_min_score: float = 1.8
    wheel_min_margin: float = 1.5
    wheel_separation: float = 0.35
    wheel_rivals: int = 2

    #: A hub found counts as a mark of this many times the marks' noise (read off the marks); one
    #: the fit puts more than ``wheel_robust_scale`` of those from it is weighted down (Cauchy),
    #: over ``wheel_passes`` solves.
    wheel_noise_ratio: float = 1.5
    wheel_robust_scale: float = 2.5
    wheel_passes: int = 3

    #: The hubs are looked for this many times, each at the car fitted to those found before.
    wheel_rounds: int = 2

    #: With hubs found, the body's height on its wheels joins the shape prior at this standard
    #: deviation, normalised units (≈ 54 mm at a 2.7 m wheelbase): the templates share one arch
    #: clearance, real cars range from lowered to lifted (0: the library's alone).
    wheel_ride_height_sd: float = 20.0


#: The policy every fit uses unless told another.
FIT_POLICY = FitPolicy()
