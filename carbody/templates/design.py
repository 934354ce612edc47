"""Parametric template builder: a design table of a few dozen numbers -> the 70 cubic Bezier curves.

A car is described by its published dimensions (length, width, height, wheelbase, front overhang,
track, tyre radius, ground clearance) and its class. The class gives the proportions of the
body (where the windshield starts, how high the belt line runs, ...) as fractions of the
wheelbase, height and half width; any of those can be overridden per car. The builder places the
58 junctions of the topology in the car frame (SPEC "Frames and units": x lateral, y from the
front wheel centre backwards, z up from the wheel centres, millimetres) and joins them with
cubic Bezier curves whose tangents make smooth chains.

The built body is sized so that its measured length, width and height are the published ones:
the foremost and rearmost points, the roof's highest point and the widest point are placed
exactly (see :func:`_solve_bulge` and the clamps in :func:`build_wireframe`).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

from carbody.errors import TemplateError
from carbody.topology import Topology, load_topology

#: Proportions by class. Stations ``*_y`` are fractions of the wheelbase behind the front wheel
#: centre, heights ``*_h`` fractions of the overall height above the ground, widths ``*_w``
#: fractions of the half width.
CLASS_PROFILES: dict[str, dict[str, float]] = {
    "sedan": dict(
        front_bumper_h=0.15, nose_h=0.52, cowl_y=0.27, cowl_h=0.66, roof_front_y=0.62,
        roof_rear_y=0.99, deck_y=1.19, deck_h=0.71, tail_h=0.70, rear_bumper_h=0.17,
        belt_front_h=0.64, belt_rear_h=0.69, sill_h=0.30, b_pillar_y=0.7, window_rear_y=0.97,
        roof_w=0.72, belt_w=0.93, tail_setback=0.035,
    ),
    "hatchback": dict(
        front_bumper_h=0.15, nose_h=0.53, cowl_y=0.27, cowl_h=0.66, roof_front_y=0.6,
        roof_rear_y=1.17, deck_y=1.235, deck_h=0.66, tail_h=0.60, rear_bumper_h=0.18,
        belt_front_h=0.64, belt_rear_h=0.69, sill_h=0.30, b_pillar_y=0.68, window_rear_y=1.02,
        roof_w=0.72, belt_w=0.93, tail_setback=0.012,
    ),
    "suv": dict(
        front_bumper_h=0.20, nose_h=0.57, cowl_y=0.28, cowl_h=0.66, roof_front_y=0.57,
        roof_rear_y=1.27, deck_y=1.33, deck_h=0.63, tail_h=0.57, rear_bumper_h=0.22,
        belt_front_h=0.63, belt_rear_h=0.66, sill_h=0.30, b_pillar_y=0.66, window_rear_y=1.1,
        roof_w=0.75, belt_w=0.93, tail_setback=0.012,
    ),
    "wagon": dict(
        front_bumper_h=0.15, nose_h=0.52, cowl_y=0.3, cowl_h=0.66, roof_front_y=0.63,
        roof_rear_y=1.27, deck_y=1.32, deck_h=0.68, tail_h=0.62, rear_bumper_h=0.18,
        belt_front_h=0.64, belt_rear_h=0.69, sill_h=0.30, b_pillar_y=0.7, window_rear_y=1.14,
        roof_w=0.71, belt_w=0.93, tail_setback=0.012,
    ),
    "coupe": dict(
        front_bumper_h=0.14, nose_h=0.55, cowl_y=0.36, cowl_h=0.68, roof_front_y=0.72,
        roof_rear_y=0.98, deck_y=1.25, deck_h=0.73, tail_h=0.72, rear_bumper_h=0.18,
        belt_front_h=0.66, belt_rear_h=0.72, sill_h=0.30, b_pillar_y=0.85, window_rear_y=0.97,
        roof_w=0.68, belt_w=0.92, tail_setback=0.03,
    ),
    "sports": dict(
        front_bumper_h=0.13, nose_h=0.50, cowl_y=0.2, cowl_h=0.68, roof_front_y=0.55,
        roof_rear_y=0.93, deck_y=1.33, deck_h=0.72, tail_h=0.71, rear_bumper_h=0.19,
        belt_front_h=0.66, belt_rear_h=0.74, sill_h=0.30, b_pillar_y=0.75, window_rear_y=0.95,
        roof_w=0.66, belt_w=0.90, tail_setback=0.03,
    ),
    "roadster": dict(
        front_bumper_h=0.15, nose_h=0.55, cowl_y=0.42, cowl_h=0.73, roof_front_y=0.66,
        roof_rear_y=0.97, deck_y=1.08, deck_h=0.74, tail_h=0.73, rear_bumper_h=0.19,
        belt_front_h=0.71, belt_rear_h=0.74, sill_h=0.33, b_pillar_y=0.85, window_rear_y=0.95,
        roof_w=0.68, belt_w=0.91, tail_setback=0.03,
    ),
    "pickup": dict(
        front_bumper_h=0.20, nose_h=0.60, cowl_y=0.22, cowl_h=0.66, roof_front_y=0.38,
        roof_rear_y=0.84, deck_y=0.875, deck_h=0.62, tail_h=0.61, rear_bumper_h=0.26,
        belt_front_h=0.63, belt_rear_h=0.64, sill_h=0.30, b_pillar_y=0.55, window_rear_y=0.82,
        roof_w=0.77, belt_w=0.94, tail_setback=0.006,
    ),
    "mpv": dict(
        front_bumper_h=0.17, nose_h=0.50, cowl_y=0.16, cowl_h=0.59, roof_front_y=0.42,
        roof_rear_y=1.24, deck_y=1.3, deck_h=0.62, tail_h=0.56, rear_bumper_h=0.20,
        belt_front_h=0.58, belt_rear_h=0.61, sill_h=0.28, b_pillar_y=0.52, window_rear_y=1.12,
        roof_w=0.76, belt_w=0.93, tail_setback=0.012,
    ),
    # Superminis: a short nose and a tail cut off just behind the rear wheel, an upright hatch
    # and glass well inboard of the shoulders (a narrow, tall cabin on a short wheelbase).
    "city": dict(
        front_bumper_h=0.16, nose_h=0.55, cowl_y=0.22, cowl_h=0.66, roof_front_y=0.56,
        roof_rear_y=1.13, deck_y=1.19, deck_h=0.66, tail_h=0.60, rear_bumper_h=0.19,
        belt_front_h=0.63, belt_rear_h=0.68, sill_h=0.30, b_pillar_y=0.64, window_rear_y=1.0,
        roof_w=0.74, belt_w=0.93, tail_setback=0.012,
    ),
    # Compact MPVs (Sienta, Freed, Touran): the minivan's one-box cabin on a small car's
    # platform, so a shorter rear overhang than "mpv" and the windshield base nearer the axle.
    "compact_mpv": dict(
        front_bumper_h=0.16, nose_h=0.50, cowl_y=0.08, cowl_h=0.58, roof_front_y=0.40,
        roof_rear_y=1.16, deck_y=1.205, deck_h=0.58, tail_h=0.54, rear_bumper_h=0.19,
        belt_front_h=0.57, belt_rear_h=0.61, sill_h=0.28, b_pillar_y=0.50, window_rear_y=1.06,
        roof_w=0.77, belt_w=0.94, tail_setback=0.01,
    ),
    # Small crossovers: a hatchback raised on bigger wheels (higher bumpers and belt), the roof
    # falling to a raked tailgate, so the side glass ends well ahead of the tail.
    "crossover": dict(
        front_bumper_h=0.19, nose_h=0.56, cowl_y=0.27, cowl_h=0.65, roof_front_y=0.58,
        roof_rear_y=1.16, deck_y=1.24, deck_h=0.64, tail_h=0.59, rear_bumper_h=0.22,
        belt_front_h=0.62, belt_rear_h=0.67, sill_h=0.31, b_pillar_y=0.66, window_rear_y=1.04,
        roof_w=0.72, belt_w=0.93, tail_setback=0.02,
    ),
    # Cab-over vans: the windshield base sits ahead of the front axle (negative cowl_y) above a
    # short sloping nose, a long flat roof ends at an upright tailgate; the glass is low and
    # wide (a tall, square cross-section).
    "van": dict(
        front_bumper_h=0.14, nose_h=0.40, cowl_y=-0.15, cowl_h=0.50, roof_front_y=0.08,
        roof_rear_y=1.36, deck_y=1.40, deck_h=0.55, tail_h=0.50, rear_bumper_h=0.17,
        belt_front_h=0.50, belt_rear_h=0.52, sill_h=0.25, b_pillar_y=0.35, window_rear_y=1.25,
        roof_w=0.85, belt_w=0.95, tail_setback=0.006,
    ),
}

#: Defaults shared by every class (mm unless said otherwise).
COMMON_DEFAULTS: dict[str, float] = dict(
    tyre_width=225.0,  # mm
    arch_clearance=55.0,  # mm between tyre and arch lip
    nose_setback=90.0,  # mm the hood front edge sits behind the foremost point
    bumper_setback=70.0,  # mm the bumper bottom sits behind the foremost point
    front_corner_setback=260.0,  # mm plan-view rounding of the front corners
    rear_corner_setback=200.0,  # mm plan-view rounding of the rear corners
    roof_front_drop=18.0,  # mm the roof front centre sits below the roof's top
    roof_rear_drop=45.0,  # mm
    roof_side_drop=45.0,  # mm the roof side edge sits below the centre line
    rail_height=75.0,  # mm from roof side edge down to the side glass top
    hood_crown=0.012,  # fraction of hood length the hood centre line bulges up
    glass_bulge=0.025,  # fraction of glass length the glass centre line bulges out
    corner_w=0.86,  # front/rear top corner half width, fraction of half width
    hood_edge_dip=30.0,  # mm the hood front edge's middle sags below its nose-to-corner arc
    sill_inset=28.0,  # mm the sill bottom sits inside the widest point
)


@dataclass
class DesignTable:
    """One car's design table: published dimensions, class, and detail proportions.

    Args:
        name: the car, e.g. ``"Toyota Camry XV70"`` (the STEP product name).
        car_class: a key of :data:`CLASS_PROFILES`.
        length, width, height, wheelbase, front_overhang: published sizes, mm.
        track_front, track_rear: published tracks, mm.
        tyre_radius: outer tyre radius, mm (wheel centres sit this high above the ground).
        ground_clearance: height of the sill bottom above the ground, mm.
        details: overrides of class proportions or common defaults (see the module tables).
        source: where the published figures come from.
    """

    name: str
    car_class: str
    length: float
    width: float
    height: float
    wheelbase: float
    front_overhang: float
    track_front: float
    track_rear: float
    tyre_radius: float
    ground_clearance: float
    details: dict[str, float] = field(default_factory=dict)
    source: str = ""

    def __post_init__(self) -> None:
        if self.car_class not in CLASS_PROFILES:
            raise TemplateError(f"{self.name}: unknown class {self.car_class!r} "
                                f"(known: {', '.join(CLASS_PROFILES)})")
        for key in ("length", "width", "height", "wheelbase", "front_overhang", "tyre_radius"):
            value = getattr(self, key)
            if not np.isfinite(value) or value <= 0:
                raise TemplateError(f"{self.name}: {key} must be a positive number, got {value!r}")
        if self.rear_overhang <= 0:
            raise TemplateError(f"{self.name}: length - wheelbase - front_overhang must be positive")
        unknown = set(self.details) - set(CLASS_PROFILES[self.car_class]) - set(COMMON_DEFAULTS)
        if unknown:
            raise TemplateError(f"{self.name}: unknown design detail(s) {sorted(unknown)}")

    @property
    def rear_overhang(self) -> float:
        return self.length - self.wheelbase - self.front_overhang

    def param(self, key: str) -> float:
        """A detail proportion: the car's override, else its class's, else the common default."""
        if key in self.details:
            return float(self.details[key])
        profile = CLASS_PROFILES[self.car_class]
        return float(profile[key] if key in profile else COMMON_DEFAULTS[key])

    @classmethod
    def from_dict(cls, data: dict) -> "DesignTable":
        try:
            return cls(**data)
        except TypeError as exc:
            raise TemplateError(f"design table {data.get('name', '?')}: {exc}") from None


def load_design_tables(path: str | Path | None = None) -> list[DesignTable]:
    """Read the design tables (JSON list); the shipped one by default."""
    if path is None:
        from importlib import resources

        text = resources.files("carbody.templates").joinpath("design_table.json").read_text()
    else:
        try:
            text = Path(path).read_text()
        except OSError as exc:
            raise TemplateError(f"{path}: cannot read design table ({exc.strerror})") from None
    try:
        rows = json.loads(text)
    except json.JSONDecodeError as exc:
        raise TemplateError(f"{path or 'design_table.json'}: not JSON ({exc.msg}, line {exc.lineno})") from None
    return [DesignTable.from_dict(r) for r in rows]


# --------------------------------------------------------------------------- curve helpers


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    return v / n if n > 0 else v


def smooth_chain(points: list[np.ndarray], start_tangent=None, end_tangent=None) -> list[np.ndarray]:
    """Cubic Bezier pieces through ``points`` with shared tangent directions at inner points.

    Inner tangents bisect the neighbouring chords; a free end mirrors its neighbour's tangent
    about the end chord (a circular-arc-like end). Handles are a third of each chord.

    Returns:
        one (4, 3) control-point array per piece.
    """
    pts = [np.asarray(p, float) for p in points]
    n = len(pts)
    chords = [_unit(pts[i + 1] - pts[i]) for i in range(n - 1)]
    tangents: list[np.ndarray | None] = [None] * n
    for i in range(1, n - 1):
        tangents[i] = _unit(chords[i - 1] + chords[i])
    tangents[0] = None if start_tangent is None else _unit(np.asarray(start_tangent, float))
    tangents[-1] = None if end_tangent is None else _unit(np.asarray(end_tangent, float))
    if tangents[0] is None and tangents[-1] is None and n == 2:
        tangents[0] = tangents[-1] = chords[0]
    if tangents[0] is None:
        tangents[0] = _unit(2 * chords[0] * np.dot(chords[0], tangents[1]) - tangents[1])
    if tangents[-1] is None:
        tangents[-1] = _unit(2 * chords[-1] * np.dot(chords[-1], tangents[-2]) - tangents[-2])
    pieces = []
    for i in range(n - 1):
        h = np.linalg.norm(pts[i + 1] - pts[i]) / 3.0
        pieces.append(np.array([pts[i], pts[i] + h * tangents[i], pts[i + 1] - h * tangents[i + 1], pts[i + 1]]))
    return pieces


def arc_pieces(centre, radius: float, angles_deg: list[float], x: float) -> list[np.ndarray]:
    """Cubic Bezier approximations of a circular arc in the plane x = const.

    Angles are measured in the yz plane from +y towards +z; one piece per consecutive pair.
    """
    pieces = []
    cy, cz = centre
    for a0, a1 in zip(angles_deg[:-1], angles_deg[1:]):
        t0, t1 = np.radians(a0), np.radians(a1)
        k = 4.0 / 3.0 * np.tan((t1 - t0) / 4.0) * radius
        p0 = np.array([x, cy + radius * np.cos(t0), cz + radius * np.sin(t0)])
        p3 = np.array([x, cy + radius * np.cos(t1), cz + radius * np.sin(t1)])
        d0 = np.array([0.0, -np.sin(t0), np.cos(t0)])
        d1 = np.array([0.0, -np.sin(t1), np.cos(t1)])
        pieces.append(np.array([p0, p0 + k * d0, p3 - k * d1, p3]))
    return pieces


def _solve_bulge(p0: np.ndarray, p3: np.ndarray, target: float, axis: int, heights=(0.3, 0.75)) -> np.ndarray:
    """A cubic from p0 to p3 whose extreme coordinate along ``axis`` is exactly ``target``.

    Both inner control points share one coordinate m on ``axis`` (the bulge of a bumper seen
    from the side); m is solved so the curve's extreme equals ``target``.
    """
    a, b = p0[axis], p3[axis]
    sign = 1.0 if target > max(a, b) else -1.0

    def extreme(m: float) -> float:
        t = np.linspace(0, 1, 2001)
        p = (1 - t) ** 3 * a + 3 * (1 - t) ** 2 * t * m + 3 * (1 - t) * t**2 * m + t**3 * b
        return (p.max() if sign > 0 else p.min()) - target

    span = abs(target - a) + abs(target - b) + 1.0
    m = brentq(extreme, target, target + sign * 4 * span, xtol=1e-10)
    p1 = p0 + heights[0] * (p3 - p0)
    p2 = p0 + heights[1] * (p3 - p0)
    p1[axis] = p2[axis] = m
    return np.array([p0, p1, p2, p3])


def _bulge(p0, p3, amount: float, direction) -> np.ndarray:
    """Midpoint of p0-p3 pushed ``amount`` (mm) along ``direction``."""
    return (np.asarray(p0) + np.asarray(p3)) / 2 + amount * _unit(np.asarray(direction, float))


def _lerp(p, q, s):
    return np.asarray(p, float) + s * (np.asarray(q, float) - np.asarray(p, float))


# --------------------------------------------------------------------------- the builder

X = np.array([1.0, 0.0, 0.0])

#: Curves whose extreme is solved exactly by :func:`_solve_bulge` (foremost and rearmost points).
BULGE_CURVES = ("front_centre", "tail_centre")


def build_junctions_and_curves(d: DesignTable) -> dict[str, np.ndarray]:
    """All 70 curves of ``d`` as {curve name: (4, 3) control points, mm}."""
    P = d.param
    wb, H, hw = d.wheelbase, d.height, d.width / 2
    zg = -d.tyre_radius  # ground
    y_front, y_rear = -d.front_overhang, wb + d.rear_overhang
    z_top = zg + H

    def h(key):  # height above ground from a class fraction
        return zg + P(key) * H

    def ys(key):  # station behind the front wheel centre from a class fraction
        return P(key) * wb

    arch_r = d.tyre_radius + P("arch_clearance")
    x_arch_f = min(hw, d.track_front / 2 + P("tyre_width") / 2 + 30.0)
    x_arch_r = min(hw, d.track_rear / 2 + P("tyre_width") / 2 + 30.0)
    x_belt = hw * P("belt_w")
    x_roof = hw * P("roof_w")
    x_sill_bottom = hw - P("sill_inset")
    z_sill_bottom = zg + d.ground_clearance
    z_sill_top = h("sill_h")
    if z_sill_bottom >= 0 or -z_sill_bottom >= arch_r:
        raise TemplateError(f"{d.name}: ground clearance must lie between the ground and the wheel centre")

    c: dict[str, np.ndarray] = {}

    def put(base: str, pieces: list[np.ndarray]):
        if len(pieces) == 1:
            c[base] = pieces[0]
        else:
            for i, piece in enumerate(pieces):
                c[f"{base}_{i + 1}"] = piece

    # ---- centre line (x = 0)
    fbbc = np.array([0, y_front + P("bumper_setback"), h("front_bumper_h")])
    nose = np.array([0, y_front + P("nose_setback"), h("nose_h")])
    cowl_c = np.array([0, ys("cowl_y"), h("cowl_h")])
    rfc = np.array([0, ys("roof_front_y"), z_top - P("roof_front_drop")])
    rrc = np.array([0, ys("roof_rear_y"), z_top - P("roof_rear_drop")])
    deck_c = np.array([0, ys("deck_y"), h("deck_h")])
    ttc = np.array([0, y_rear - P("tail_setback") * wb, h("tail_h")])
    rbbc = np.array([0, y_rear - P("bumper_setback"), h("rear_bumper_h")])
    stations = [("cowl_y", cowl_c[1]), ("roof_front_y", rfc[1]), ("roof_rear_y", rrc[1]),
                ("deck_y", deck_c[1]), ("tail", ttc[1])]
    for (k0, y0), (k1, y1) in zip(stations[:-1], stations[1:]):
        if not y0 + 50 < y1:
            raise TemplateError(f"{d.name}: station {k0} ({y0:.0f} mm) must lie ahead of {k1} ({y1:.0f} mm)")
    if nose[1] >= cowl_c[1] - 100:
        raise TemplateError(f"{d.name}: the hood is too short (cowl_y)")

    c["front_centre"] = _solve_bulge(fbbc, nose, y_front, axis=1)
    hood_len = cowl_c[1] - nose[1]
    up = np.array([0, 0, 1.0])
    put("hood_centre", smooth_chain(
        [nose, _lerp(nose, cowl_c, 1 / 3) + up * P("hood_crown") * hood_len * 1.6,
         _lerp(nose, cowl_c, 2 / 3) + up * P("hood_crown") * hood_len * 1.2, cowl_c],
        start_tangent=[0, 1, 0.08]))

    def glass_mid(p, q):  # the glass centre line bulges outwards (away from the cabin)
        chord = q - p
        normal = np.array([0, -chord[2], chord[1]]) if chord[1] > 0 else np.array([0, chord[2], -chord[1]])
        if normal[2] < 0:
            normal = -normal
        return _bulge(p, q, P("glass_bulge") * np.linalg.norm(chord), normal)

    put("windshield_centre", smooth_chain([cowl_c, glass_mid(cowl_c, rfc), rfc]))
    roof_len = rrc[1] - rfc[1]
    rca = np.array([0, rfc[1] + 0.38 * roof_len, z_top])
    rcb = np.array([0, rfc[1] + 0.72 * roof_len, z_top - 0.45 * P("roof_rear_drop")])
    put("roof_centre", smooth_chain([rfc, rca, rcb, rrc]))
    put("rear_window_centre", smooth_chain([rrc, glass_mid(rrc, deck_c), deck_c]))
    trunk_len = ttc[1] - deck_c[1]
    put("trunk_centre", smooth_chain(
        [deck_c, _lerp(deck_c, ttc, 1 / 3) + up * 0.015 * trunk_len,
         _lerp(deck_c, ttc, 2 / 3) + up * 0.012 * trunk_len, ttc]))
    c["tail_centre"] = _solve_bulge(ttc, rbbc, y_rear, axis=1, heights=(0.25, 0.7))

    # ---- front face and tail
    ftc = np.array([hw * P("corner_w"), y_front + P("front_corner_setback"), nose[2] - 25])
    fbc = np.array([hw * 0.92, y_front + P("front_corner_setback") * 0.8 + P("bumper_setback"),
                    fbbc[2] + 30])
    rtc = np.array([hw * P("corner_w"), y_rear - P("rear_corner_setback") - P("tail_setback") * wb,
                    ttc[2] - 20])
    rbc = np.array([hw * 0.92, y_rear - P("rear_corner_setback") * 0.8 - P("bumper_setback"),
                    rbbc[2] + 30])
    # A bonnet's shut line runs down over the headlamps' tops between the nose and the corner.
    # Lowering the inner handle at the corner sags the edge's middle by 3/8 of it; the nose's
    # handle stays level, so the edge and its mirror meet smoothly on the centre line.
    c["hood_front_edge"] = smooth_chain([nose, ftc], start_tangent=X)[0]
    c["hood_front_edge"][2, 2] -= P("hood_edge_dip") * 8.0 / 3.0
    c["tail_top_edge"] = smooth_chain([ttc, rtc], start_tangent=X)[0]

    def bottom_mid(centre, corner):
        s = 0.6
        return np.array([s * corner[0], centre[1] + (corner[1] - centre[1]) * s**2.2,
                         centre[2] + (corner[2] - centre[2]) * s**2])

    put("front_bottom", smooth_chain([fbbc, bottom_mid(fbbc, fbc), fbc], start_tangent=X))
    put("rear_bottom", smooth_chain([rbbc, bottom_mid(rbbc, rbc), rbc], start_tangent=X))
    c["front_corner"] = smooth_chain([ftc, fbc], start_tangent=[0, -0.35, -1], end_tangent=[0, 0.3, -1])[0]
    c["rear_corner"] = smooth_chain([rtc, rbc], start_tangent=[0, 0.25, -1], end_tangent=[0, -0.3, -1])[0]

    # ---- transverse edges of hood, glass, roof, deck
    def belt_z(y):
        y0, y1 = cowl_c[1], P("window_rear_y") * wb
        s = np.clip((y - y0) / (y1 - y0), 0, 1.3)
        return h("belt_front_h") + s * (h("belt_rear_h") - h("belt_front_h"))

    apb = np.array([x_belt, cowl_c[1] + 110, belt_z(cowl_c[1] + 110)])
    c["cowl"] = smooth_chain([cowl_c, apb], start_tangent=X)[0]
    rfk = np.array([x_roof, rfc[1] + 130, rfc[2] - P("roof_side_drop")])
    rrk = np.array([x_roof * 0.98, rrc[1] - 110, rrc[2] - P("roof_side_drop")])
    c["windshield_top"] = smooth_chain([rfc, rfk], start_tangent=X)[0]
    c["roof_rear_edge"] = smooth_chain([rrc, rrk], start_tangent=X)[0]
    deck_k = np.array([hw * 0.9, deck_c[1] - 90, deck_c[2] - 30])
    c["deck_edge"] = smooth_chain([deck_c, deck_k], start_tangent=X)[0]

    # ---- side: hood side (fender top), pillars, roof side, trunk side
    x_fender = hw * 0.95
    put("hood_side", smooth_chain(
        [ftc, np.array([x_fender, _lerp(ftc, apb, 1 / 3)[1], _lerp(ftc, apb, 1 / 3)[2] + 10]),
         np.array([x_fender, _lerp(ftc, apb, 2 / 3)[1], _lerp(ftc, apb, 2 / 3)[2] + 5]), apb]))
    put("a_pillar", smooth_chain([apb, glass_mid(apb, rfk) + X * 12, rfk]))
    rs_len = rrk[1] - rfk[1]
    put("roof_side", smooth_chain(
        [rfk, np.array([x_roof + 8, rfk[1] + 0.36 * rs_len, rca[2] - P("roof_side_drop") - 5]),
         np.array([x_roof + 5, rfk[1] + 0.7 * rs_len, rcb[2] - P("roof_side_drop") - 5]), rrk]))
    put("c_pillar", smooth_chain([rrk, glass_mid(rrk, deck_k) + X * 15, deck_k]))
    put("trunk_side", smooth_chain(
        [deck_k, _lerp(deck_k, rtc, 1 / 3) + np.array([12, 0, 0.012 * trunk_len]),
         _lerp(deck_k, rtc, 2 / 3) + np.array([10, 0, 0.01 * trunk_len]), rtc]))

    # ---- belt line and side glass
    y_wr = P("window_rear_y") * wb
    wfb = np.array([x_belt + 4, apb[1] + 140, belt_z(apb[1] + 140)])
    wrb = np.array([x_belt, y_wr, belt_z(y_wr)])
    x_wtop = x_roof + 25
    z_wtop_f = rfk[2] - P("rail_height")
    wft = _lerp(apb, rfk, (z_wtop_f - apb[2]) / (rfk[2] - apb[2]))  # on the A-pillar line
    wft = np.array([x_wtop, wft[1] + 90, z_wtop_f])
    wrt = np.array([x_wtop, min(rrk[1] - 120, y_wr - 60), rrk[2] - P("rail_height")])
    if wrt[1] <= wft[1] + 300:
        raise TemplateError(f"{d.name}: the side glass is too short (window_rear_y, roof stations)")
    # The B-pillar stands between the glass's front top corner and its rear corners.
    y_b = float(np.clip(P("b_pillar_y") * wb, wft[1] + 120, min(wrt[1], y_wr) - 150))
    bpb = np.array([x_belt + 8, y_b, belt_z(y_b)])
    brd = np.array([x_belt + 6, (y_b + y_wr) / 2, belt_z((y_b + y_wr) / 2)])
    c["belt_front"] = smooth_chain([apb, wfb])[0]
    put("belt", smooth_chain([wfb, bpb, brd, wrb]))
    c["belt_rear"] = smooth_chain([wrb, deck_k])[0]

    z_rail = lambda y: np.interp(y, [rfk[1], rfk[1] + 0.36 * rs_len, rfk[1] + 0.7 * rs_len, rrk[1]],
                                 [rfk[2], rca[2] - P("roof_side_drop"), rcb[2] - P("roof_side_drop"), rrk[2]])
    bpt = np.array([x_wtop + 4, y_b, z_rail(y_b) - P("rail_height")])
    wtr = np.array([x_wtop + 3, (y_b + wrt[1]) / 2, z_rail((y_b + wrt[1]) / 2) - P("rail_height")])
    c["window_front_edge"] = smooth_chain([wfb, wft])[0]
    put("window_top", smooth_chain([wft, bpt, wtr, wrt]))
    c["window_rear_edge"] = smooth_chain([wrt, wrb])[0]

    # ---- wheel arches (circles round the wheel centres, straight below the centre line)
    def arch(y_centre, x_lip, front_end_z, rear_end_z, front_x, rear_x):
        quarter = arc_pieces((y_centre, 0.0), arch_r, [180.0, 90.0, 0.0], x_lip)
        p_front, p_rear = quarter[0][0], quarter[-1][-1]
        end_f = np.array([front_x, y_centre - arch_r - 12, front_end_z])
        end_r = np.array([rear_x, y_centre + arch_r + 12, rear_end_z])
        down = np.array([0, 0, -1.0])
        first = smooth_chain([end_f, p_front], start_tangent=-down, end_tangent=-down)[0]
        last = smooth_chain([p_rear, end_r], start_tangent=down, end_tangent=down)[0]
        return [first, *quarter, last]

    # The arch runs down to the bumper line, but always well below the wheel centre (a tall
    # SUV bumper would otherwise leave no arch below the centre line).
    front_end_z = min(fbc[2], -0.35 * arch_r)
    rear_end_z = min(rbc[2], -0.35 * arch_r)
    front_arch = arch(0.0, x_arch_f, front_end_z, z_sill_bottom, x_arch_f - 10, x_sill_bottom)
    rear_arch = arch(wb, x_arch_r, z_sill_bottom, rear_end_z, x_sill_bottom, x_arch_r - 10)
    put("front_arch", front_arch)
    put("rear_arch", rear_arch)
    sill_f, sill_r = front_arch[-1][-1], rear_arch[0][0]
    c["fender_bottom"] = smooth_chain([front_arch[0][0], fbc], start_tangent=[0, -1, 0])[0]
    c["rear_fender_bottom"] = smooth_chain([rear_arch[-1][-1], rbc], start_tangent=[0, 1, 0])[0]

    # ---- doors and sill
    dfb = np.array([hw, sill_f[1] + 70, z_sill_top])
    drb = np.array([hw, sill_r[1] - 70, z_sill_top])
    # The B-pillar foot stays ahead of the rear door shut line (a coupe's long door).
    bps = np.array([hw, min(y_b, dfb[1] + 0.6 * (drb[1] - dfb[1])), z_sill_top])
    srd = np.array([hw, (bps[1] + drb[1]) / 2, z_sill_top])
    put("sill_top", smooth_chain([dfb, bps, srd, drb], start_tangent=[0, 1, 0], end_tangent=[0, 1, 0]))
    c["sill_front_end"] = smooth_chain([dfb, sill_f], end_tangent=[0, 0, -1])[0]
    c["sill_rear_end"] = smooth_chain([drb, sill_r], end_tangent=[0, 0, -1])[0]
    put("sill_bottom", smooth_chain(
        [sill_f, _lerp(sill_f, sill_r, 1 / 3), _lerp(sill_f, sill_r, 2 / 3), sill_r]))
    # Door shut lines leave the belt line heading down along their chord (not back along the
    # belt) and turn towards the vertical at the sill, so the door, fender and rear-quarter
    # regions have a real corner at the belt and a simple, non-crossing outline.
    down = np.array([0, 0, -1.0])
    c["door_front_edge"] = smooth_chain([wfb, dfb], start_tangent=_unit(dfb - wfb),
                                        end_tangent=_unit(dfb - wfb) + down)[0]
    c["door_rear_edge"] = smooth_chain([wrb, drb], start_tangent=_unit(drb - wrb),
                                       end_tangent=_unit(drb - wrb) + down)[0]
    return c


def build_wireframe(d: DesignTable, topology: Topology | None = None) -> np.ndarray:
    """Control points of the car's 70 curves in topology order.

    Returns:
        (280, 3) float, mm, car frame; curve i owns rows 4i..4i+3.
    Raises:
        TemplateError: a design table that gives no valid body.
    """
    topo = topology or load_topology()
    curves = build_junctions_and_curves(d)
    missing = {cv.name for cv in topo.curves} - set(curves)
    if missing:  # a builder bug, not a user error
        raise AssertionError(f"builder does not make curves {sorted(missing)}")
    pts = np.concatenate([curves[cv.name] for cv in topo.curves])
    # Convex hull: clamping control points keeps every curve inside the published box, and the
    # junctions placed on the box's faces make the box tight.
    # The two bumper profiles reach the length exactly through control points beyond it.
    hw = d.width / 2
    clamp_y = np.ones(len(pts), bool)
    for name in BULGE_CURVES:
        i = topo.curve(name).index
        clamp_y[4 * i:4 * i + 4] = False
    pts[:, 0] = np.clip(pts[:, 0], 0.0, hw)
    pts[clamp_y, 1] = np.clip(pts[clamp_y, 1], -d.front_overhang, d.wheelbase + d.rear_overhang)
    pts[:, 2] = np.minimum(pts[:, 2], d.height - d.tyre_radius)
    _check_junctions(pts, topo, d.name)
    return pts


def _check_junctions(pts: np.ndarray, topo: Topology, name: str) -> None:
    for junction, idx in topo.junction_groups().items():
        spread = np.ptp(pts[idx], axis=0).max()
        if spread > 1e-9:
            raise AssertionError(f"{name}: curves do not meet at {junction} (spread {spread:g} mm)")
