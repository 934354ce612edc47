"""The surface pipeline: wireframe -> 13 regions -> skeletons -> control nets -> sewn Bezier shell.

``build_body(wireframe)`` is the one call (the view classifier and the CLI use it)::

    from carbody.surface import build_body
    body = build_body(wireframe)      # a carbody.wireframe.Wireframe (mm)
    body.shape                        # TopoDS_Shell, both halves, sewn
    body.faces                        # [(region name, TopoDS_Face)], every face of body.shape
    body.report                       # quality figures (see build_body)

Each region is laid out the paper's way (projection onto its best-fit plane, skeleton, ribs);
where that fails on a wireframe (its outline folds in the plane, its ribs cross), by arc length
from its boundary curves alone (:mod:`carbody.surface.arc_layout`). Either way every face edge
on a wireframe curve is an exact sub-arc of it, and the report says which layout each region got.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from carbody.errors import RegionLayoutError, SurfaceError
from carbody.surface.arc_layout import arc_length_net
from carbody.surface.control_net import FacePatch, RegionNet, region_net
from carbody.surface.quality import region_report, seam_quality
from carbody.surface.regions import (BEGIN, END, BoundarySamples, RegionOutline, bezier_points,
                                     boundary_samples, region_outlines)
from carbody.surface.skeleton import OptimalPair, optimal_pairs, skeleton_line
from carbody.tolerances import NORMALISED_WHEELBASE, SKELETON_SPACING_NORM
from carbody.topology import Topology, load_topology

#: A sewn shell's free edges may differ from the body's openings' length by this fraction.
OPENING_LENGTH_REL = 1e-3

#: A part is not bisected when a side would be thinner than this many sample spacings.
MIN_HEIGHT_SPACINGS = 2.0

#: Ribs closer than this many sample spacings (arc length on a side) are merged.
MIN_GAP_SPACINGS = 0.6


@dataclass
class RegionSkeleton:
    """One region's skeleton (paper IV): samples, optimal pairs and the skeleton line.

    ``line`` is (k, 2) in the samples' plane frame (normalised units).
    """

    outline: RegionOutline
    samples: BoundarySamples
    pairs: list[OptimalPair]
    line: np.ndarray


@dataclass
class Body:
    """A surfaced car body.

    Attributes:
        name: the car.
        shape: the sewn ``TopoDS_Shell`` of both halves (mm).
        faces: [(region name, TopoDS_Face)] for every face of ``shape``, left half first.
        report: quality figures: per region (faces, inner G0/G1, min scaled Jacobian), per seam
            (G0 gap, G1 angle), shell checks, stage timings.
        patches: the faces as Bezier nets (numpy), same order as ``faces``.
        nets: each region's ribs and control curves.
    """

    name: str
    shape: Any
    faces: list[tuple[str, Any]]
    report: dict
    patches: list[FacePatch] = field(default_factory=list)
    nets: list[RegionNet] = field(default_factory=list)


def wheelbase_of(control_points: np.ndarray, topology: Topology | None = None) -> float:
    """Wheelbase (mm) of a wireframe: distance between its two wheel centres in side view.

    Raises:
        SurfaceError: the wheel centres coincide (or are not numbers).
    """
    from carbody.wireframe import wheel_centre

    topo = topology or load_topology()
    f, r = (wheel_centre(control_points, topo, s) for s in ("front", "rear"))
    wheelbase = float(np.hypot(*(r - f)))
    if not 0 < wheelbase < np.inf:
        raise SurfaceError(f"the wheel centres (between junctions {', '.join(topo.wheel_centres['front'])} and "
                           f"{', '.join(topo.wheel_centres['rear'])}) are {wheelbase:.3g} mm apart: no wheelbase "
                           f"to space the surfaces' samples by")
    return wheelbase


def region_skeleton(outline: RegionOutline, wheelbase_mm: float,
                    spacing_norm: float = SKELETON_SPACING_NORM) -> RegionSkeleton:
    """Project, sample and run Algorithm 1 on one region (paper IV.B–C)."""
    samples = boundary_samples(outline, wheelbase_mm, spacing_norm)
    pairs = optimal_pairs(samples.points2d, samples.normals2d, min_height=MIN_HEIGHT_SPACINGS * spacing_norm)

    def middle(label):
        idx = np.flatnonzero(samples.side == label)
        return int(idx[len(idx) // 2]) if len(idx) else 0

    line = skeleton_line(samples.points2d, pairs, middle(BEGIN), middle(END))
    return RegionSkeleton(outline, samples, pairs, line)


def skeletons(control_points: np.ndarray, wheelbase_mm: float | None = None,
              topology: Topology | None = None) -> list[RegionSkeleton]:
    """Skeletons of all regions of a wireframe (mm)."""
    topo = topology or load_topology()
    wb = wheelbase_mm or wheelbase_of(control_points, topo)
    return [region_skeleton(o, wb) for o in region_outlines(control_points, topo)]


def region_layout(outline: RegionOutline, wheelbase_mm: float,
                  timings: dict | None = None) -> tuple[RegionNet, RegionSkeleton | None]:
    """One region's control net: the paper's layout (projection, skeleton, ribs), or, where that
    fails on this wireframe (:class:`~carbody.errors.RegionLayoutError`: the outline folds in its
    best-fit plane, the ribs cross), the layout by arc length
    (:mod:`carbody.surface.arc_layout`), which needs no projection.

    Returns:
        (net, skeleton); skeleton is None for a region laid out by arc length.
    Raises:
        SurfaceError: the region is degenerate in 3D (no layout can surface it).
    """
    min_gap_mm = MIN_GAP_SPACINGS * SKELETON_SPACING_NORM * wheelbase_mm / NORMALISED_WHEELBASE
    timings = {} if timings is None else timings
    t0 = time.perf_counter()
    try:
        sk = region_skeleton(outline, wheelbase_mm)
        t1 = time.perf_counter()
        net = region_net(sk.outline, sk.samples, sk.pairs, min_gap_mm)
    except RegionLayoutError as exc:
        t1 = time.perf_counter()
        sk, net = None, arc_length_net(outline, min_gap_mm, reason=str(exc))
    t2 = time.perf_counter()
    timings["skeleton_s"] = timings.get("skeleton_s", 0.0) + t1 - t0
    timings["control_nets_s"] = timings.get("control_nets_s", 0.0) + t2 - t1
    return net, sk


def region_patches(control_points: np.ndarray, topology: Topology | None = None,
                   timings: dict | None = None, outlines: list[RegionOutline] | None = None
                   ) -> tuple[list[RegionNet], list[RegionSkeleton | None]]:
    """Control nets and Bezier patches (left half) of every region (:func:`region_layout`);
    numpy only. The skeleton of a region laid out by arc length is None. ``outlines``: the
    wireframe's :func:`region_outlines`, when the caller has them already."""
    topo = topology or load_topology()
    wb = wheelbase_of(control_points, topo)
    timings = {} if timings is None else timings
    timings.update(skeleton_s=0.0, control_nets_s=0.0)
    outlines = region_outlines(control_points, topo) if outlines is None else outlines
    done = [region_layout(o, wb, timings) for o in outlines]
    return [n for n, _ in done], [s for _, s in done]


def build_body(wireframe, topology: Topology | None = None, check: bool = True) -> Body:
    """Surface a wireframe: all 13 regions and their mirror sewn into one shell.

    Args:
        wireframe: a :class:`carbody.wireframe.Wireframe` (left half, mm).
        check: run the OCCT shell checks (validity, free edges, tolerances) into the report.
    Returns:
        a :class:`Body`; ``report`` holds ``regions`` {name: {faces, inner_g0_mm,
        inner_g1_deg, corner_ribs, corner_g1_deg, min_scaled_jacobian, min_surface_jacobian,
        pairs, ribs}}, ``seams`` {"a|b": {g0_mm, g1_deg}},
        ``shell`` {valid, faces, free_edges, free_loops, max_tolerance_mm, ...} and ``timings_s``.
        Each region also says its ``layout``: "skeleton" (the paper's) or "arc_length" (where
        the paper's fails on this wireframe; ``layout_note`` says why), its
        ``folded_area_share`` and, when it folds (:mod:`carbody.surface.folds`), ``fold``: one
        line naming it and its curves; ``folds`` lists those lines (empty for a sound body).
    Raises:
        SurfaceError: a region whose loop does not close or is degenerate (a curve of zero
            length, junctions on one spot, no area; the message names the region and curves),
            or, with ``check``, a sewn shell that is not valid or is open elsewhere than at the
            body's openings.
    """
    from carbody.occ.faces import bezier_face
    from carbody.occ.sewing import sew_faces

    topo = topology or load_topology()
    cp = wireframe.control_points
    timings: dict[str, float] = {}
    wheelbase_of(cp, topo)  # (a wireframe without a wheelbase is refused before any region is read)
    outlines = region_outlines(cp, topo)
    nets, sk = region_patches(cp, topo, timings, outlines)

    t = time.perf_counter()
    symmetric = {c.index for c in topo.curves
                 if c.start in topo.symmetry_junctions and c.end in topo.symmetry_junctions}
    left = [f for n in nets for f in n.faces]
    patches_all = left + [f.mirrored(symmetric) for f in left]
    splits = edge_splits(patches_all)
    occ_faces = [bezier_face(f.net, face_side_splits(f, splits)) for f in patches_all]
    timings["faces_s"] = time.perf_counter() - t

    t = time.perf_counter()
    shell, sewn = sew_faces(occ_faces)
    timings["sewing_s"] = time.perf_counter() - t

    report: dict[str, Any] = {"regions": {}, "seams": {}}
    from carbody.surface.folds import fold_message, region_folds

    t = time.perf_counter()
    folds = {f.region: f for f in region_folds(cp, outlines, {n.name: n.faces for n in nets}, topo)}
    timings["folds_s"] = time.perf_counter() - t
    report["folds"] = [fold_message(f) for f in folds.values() if f.folds]
    for n, s in zip(nets, sk):
        r = region_report(n.faces, n.side_turn_deg)
        r["folded_area_share"] = folds[n.name].folded_area_share
        if folds[n.name].folds:
            r["fold"] = fold_message(folds[n.name])
        r["pairs"] = len(s.pairs) if s is not None else 0
        r["ribs"] = len(n.ribs)
        r["layout"] = n.layout
        if n.layout_note:
            r["layout_note"] = n.layout_note
        report["regions"][n.name] = r
    for (a, b), (g0, g1) in sorted(seam_quality(patches_all).items()):
        report["seams"][f"{a}|{b}"] = {"g0_mm": g0, "g1_deg": g1}
    if check:
        from carbody.occ.checks import shell_checks

        t = time.perf_counter()
        report["shell"] = shell_checks(shell)
        timings["checks_s"] = time.perf_counter() - t
        refuse_bad_shell(report["shell"], patches_all, sewn, cp, topo)
    report["timings_s"] = timings
    faces = [(f.region, g) for f, g in zip(patches_all, sewn)]
    return Body(wireframe.name, shell, faces, report, patches_all, nets)


def surface_wireframe(wire, *, allow_folds: bool = False, topology: Topology | None = None) -> Body:
    """Surface an edited wireframe: :func:`build_body` on anything :func:`carbody.wireframe.as_wireframe`
    takes (a :class:`~carbody.wireframe.Wireframe`, a wireframe file, a build123d compound of
    labelled edges, a CadQuery assembly of named edges), refusing a body that folds.

    Args:
        wire: the wireframe (mm).
        allow_folds: give the body even when a region folds (its ``report["folds"]`` says where).
    Returns:
        the :class:`Body`.
    Raises:
        FoldError: a region folds (:mod:`carbody.surface.folds`): one line naming the region and
            its curves (the first of them, with how many more).
        SurfaceError: as :func:`build_body`; TemplateError: curves missing, unnamed or apart.
    """
    from carbody.errors import FoldError
    from carbody.wireframe import as_wireframe

    body = build_body(as_wireframe(wire), topology)
    folds = body.report["folds"]
    if folds and not allow_folds:
        more = len(folds) - 1
        raise FoldError(folds[0] + (f"; {more} more region{'s fold' if more > 1 else ' folds'} too" if more else ""))
    return body


def opening_length(control_points: np.ndarray, topology: Topology | None = None, samples: int = 400) -> float:
    """Length (mm, both halves) of the body's openings: the curves only one region uses that are
    not on the symmetry plane (the lower edge of the body)."""
    topo = topology or load_topology()
    used: dict[int, int] = {}
    for r in topo.regions:
        for ci, _ in r.loop:
            used[ci] = used.get(ci, 0) + 1
    t = np.linspace(0, 1, samples)
    total = 0.0
    for c in topo.curves:
        if used.get(c.index) == 1 and not (c.start in topo.symmetry_junctions and c.end in topo.symmetry_junctions):
            p = bezier_points(control_points[4 * c.index:4 * c.index + 4], t)
            total += float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
    return 2 * total


def refuse_bad_shell(shell: dict, patches: list[FacePatch], faces: list, control_points: np.ndarray,
                     topology: Topology | None = None) -> None:
    """Refuse a sewn shell that is not valid or whose free edges are not the body's openings.

    Args:
        shell: :func:`carbody.occ.checks.shell_checks` of it.
        patches, faces: its faces as nets and as sewn OCCT faces, same order.
    Raises:
        SurfaceError: naming the regions of the invalid faces, or the free length found.
    """
    from carbody.occ.checks import invalid_faces

    if not shell["valid"]:
        bad = sorted({patches[k].region + ("_right" if patches[k].mirror else "") for k in invalid_faces(faces)})
        raise SurfaceError(f"the sewn shell is not valid (BRepCheck){': faces of ' + ', '.join(bad) if bad else ''}")
    expected = opening_length(control_points, topology)
    if shell["free_open_wires"] or abs(shell["free_length_mm"] - expected) > OPENING_LENGTH_REL * expected:
        raise SurfaceError(f"the sewn shell is open elsewhere than at the body's openings: "
                           f"{shell['free_length_mm']:.0f} mm of free edges, the openings are {expected:.0f} mm")


def edge_splits(patches: list[FacePatch]) -> dict[tuple[int, bool], np.ndarray]:
    """Every face corner on each wireframe curve: {(curve, mirror): sorted curve parameters}.

    Neighbouring faces split their sides at the union, so sewing meets identical edges.
    """
    found: dict[tuple[int, bool], list[float]] = {}
    for f in patches:
        for ref in f.sides.values():
            if ref is not None:
                found.setdefault(ref.key, []).extend((ref.t0, ref.t1))
    out = {}
    for key, ts in found.items():
        ts = np.sort(np.asarray(ts))
        keep = np.r_[True, np.diff(ts) > 1e-9]
        out[key] = ts[keep]
    return out


def face_side_splits(face: FacePatch, splits: dict[tuple[int, bool], np.ndarray]) -> dict[str, np.ndarray]:
    """Each side's split parameters in [0, 1] (side parameter, both ends included)."""
    out = {}
    for side, ref in face.sides.items():
        if ref is None:
            out[side] = np.array([0.0, 1.0])
            continue
        ts = splits[ref.key]
        lo, hi = min(ref.t0, ref.t1), max(ref.t0, ref.t1)
        inner = ts[(ts > lo + 1e-9) & (ts < hi - 1e-9)]
        p = (inner - ref.t0) / (ref.t1 - ref.t0)
        out[side] = np.r_[0.0, np.sort(p), 1.0]
    return out


def region_colour(name: str, topology: Topology | None = None) -> tuple[float, float, float]:
    """sRGB colour (0..1) of a region: hues evenly spread over the topology's regions."""
    import colorsys

    topo = topology or load_topology()
    names = [r.name for r in topo.regions]
    k = names.index(name)
    return colorsys.hsv_to_rgb((k * 0.618034) % 1.0, 0.55, 0.85)


def face_names(body: Body) -> list[str]:
    """STEP face names: ``REGION_K`` on the left half, ``REGION_right_K`` on the right."""
    return [f"{p.region}{'_right' if p.mirror else ''}_{p.index}" for p in body.patches]


def write_body(path, body: Body) -> Path:
    """Write a body as AP214 STEP (mm): one shell, faces named and coloured by region."""
    from carbody.occ.step_body import write_body_step

    faces = [(n, region_colour(p.region), f) for n, p, (_, f) in zip(face_names(body), body.patches, body.faces)]
    return write_body_step(path, body.shape, faces, body.name)
