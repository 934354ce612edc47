"""Which keypoints a view can see, from the wireframe's geometry (paper III.C).

A keypoint is seen when one of the regions that meet at it faces the camera (its outward normal
has a positive component toward the camera, a grazing region counts as the silhouette) and no
nearer facing region covers it in the image. Regions are the topology's 13 closed loops on each
half; their normals come from the loop polygon (Newell's method), made outward by pointing away
from the body's centre line.

For a pinhole view (``View.distance``) "toward the camera" is toward the camera's position, which
differs from region to region: a photo from a few metres at front 60° no longer sees the nose's
face, which an orthographic camera at 60° does, and it sees less of the roof from above.
"""
from __future__ import annotations

import numpy as np

from carbody.camera import View, camera_direction, perspective_factors, project
from carbody.fit.keypoints_io import KeypointSlot, keypoint_slots
from carbody.topology import Topology, load_topology

#: A region faces the camera when n·d exceeds this: a panel seen edge-on (a door from straight
#: ahead) has its points on the silhouette, where nobody can mark them.
FACING_COS = 0.1

#: A keypoint is hidden only when it lies this far inside a nearer region's outline and that
#: region lies this far in front of it (fractions of the body length).
OCCLUSION_MARGIN = 0.02

#: Samples per curve for region outlines.
_SAMPLES = 8

def _region_loops(control_points: np.ndarray, topo: Topology) -> list[np.ndarray]:
    """(n, 3) outline per region of the left half, in loop order."""
    from carbody.wireframe import sample_curves

    curves = sample_curves(control_points, _SAMPLES)
    loops = []
    for region in topo.regions:
        parts = [curves[ci][::-1] if rev else curves[ci] for ci, rev in region.loop]
        loops.append(np.concatenate([p[:-1] for p in parts]))
    return loops


def _newell_normal(loop: np.ndarray) -> np.ndarray:
    nxt = np.roll(loop, -1, axis=0)
    n = np.array([np.sum((loop[:, 1] - nxt[:, 1]) * (loop[:, 2] + nxt[:, 2])),
                  np.sum((loop[:, 2] - nxt[:, 2]) * (loop[:, 0] + nxt[:, 0])),
                  np.sum((loop[:, 0] - nxt[:, 0]) * (loop[:, 1] + nxt[:, 1]))])
    return n / max(np.linalg.norm(n), 1e-12)


def _inside(poly: np.ndarray, q: np.ndarray) -> tuple[bool, float]:
    """Whether 2D point q lies inside polygon poly (n, 2), and its distance to the outline."""
    a, b = poly, np.roll(poly, -1, axis=0)
    crosses = ((a[:, 1] > q[1]) != (b[:, 1] > q[1]))
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = a[:, 0] + (q[1] - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    inside = bool(np.count_nonzero(crosses & (x_at > q[0])) % 2)
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", q - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
    dist = float(np.min(np.linalg.norm(a + t[:, None] * ab - q, axis=1)))
    return inside, dist


def visible_keypoints(view: View, control_points: np.ndarray | None = None,
                      topology: Topology | None = None, occlusion: bool = True) -> list[str]:
    """Names of the keypoints (both halves) the view can see, in id order, left before right.

    Args:
        view: the camera; a pinhole view's distance and aim are in the unit of ``control_points``.
        control_points: (280, 3) float, the car (any unit); default the library's mean model
            (normalised units).
        occlusion: also hide what a nearer region covers; off, a keypoint is seen when a region
            at it faces the camera (cheaper).
    Raises:
        AngleError: a pinhole camera inside the car.
    """
    topo = topology or load_topology()
    if control_points is None:
        from carbody.library import load_library

        control_points = load_library().S.mean(axis=1).reshape(-1, 3)
    cp = np.asarray(control_points, dtype=float)
    perspective_factors(cp, view)  # refuses a camera inside the car
    d = camera_direction(view)
    eye = None if view.distance is None else np.asarray(view.aim, dtype=float) + view.distance * d
    size = float(np.ptp(cp[:, 1]))
    centre_line = np.array([0.0, cp[:, 1].mean(), cp[:, 2].mean()])

    def toward_camera(p: np.ndarray) -> np.ndarray:
        """(3,) unit vector from point p toward the camera."""
        if eye is None:
            return d
        v = eye - p
        return v / np.linalg.norm(v)

    # Regions of both halves: outline (n, 3), outward normal, junction names.
    regions = []
    left_loops = _region_loops(cp, topo)
    for region, loop in zip(topo.regions, left_loops):
        n = _newell_normal(loop)
        if n @ (loop.mean(axis=0) - centre_line) < 0:
            n = -n
        junctions = set(topo.region_junctions(region))
        for sign in (np.ones(3), np.array([-1.0, 1.0, 1.0])):
            regions.append((loop * sign, n * sign, junctions, sign[0] < 0))

    facing = [r for r in regions if r[1] @ toward_camera(r[0].mean(axis=0)) > FACING_COS]
    outlines = [(project(r[0], view), r) for r in facing] if occlusion else []
    seen = []
    for slot in keypoint_slots(topo).values():
        p = cp[slot.point_index] * slot.sign
        junction = _junction_of(slot, topo)
        central = junction in topo.symmetry_junctions

        def owns(r) -> bool:  # a region the keypoint lies on (either half for a central one)
            return (central or r[3] == slot.is_mirror) and junction in r[2]

        if not any(owns(r) for r in facing):
            continue
        q = project(p, view)
        ray = toward_camera(p)
        hidden = False
        for poly, r in outlines:
            if owns(r):
                continue
            inside, dist = _inside(poly, q)
            # (the margin is a length on the car: a pinhole shows it larger near the camera)
            if not inside or dist < OCCLUSION_MARGIN * size * float(perspective_factors(p, view)):
                continue
            # How far along the ray from p toward the camera it meets the region's plane.
            nd = r[1] @ ray
            if abs(nd) < 1e-6:
                continue
            t = r[1] @ (r[0].mean(axis=0) - p) / nd
            if t > OCCLUSION_MARGIN * size:
                hidden = True
                break
        if not hidden:
            seen.append(slot.name)
    return seen


class FacingTable:
    """Which keypoints face a view, for many views at once: the facing test of
    :func:`visible_keypoints` (no occlusion, orthographic) as two small matrices, the regions'
    outward normals and which regions each keypoint lies on. Built once per car (the fit builds
    it for the library's mean car); a view's answer then costs a matrix product, so the view
    search asks it at every hypothesis.

    Attributes:
        names: the 70 keypoint names (:func:`keypoint_slots` order).
        normals: (R, 3) outward unit normals of both halves' regions.
        owner: (70, R) bool, the regions each keypoint lies on.
    """

    def __init__(self, control_points: np.ndarray, topology: Topology | None = None):
        topo = topology or load_topology()
        cp = np.asarray(control_points, dtype=float)
        centre_line = np.array([0.0, cp[:, 1].mean(), cp[:, 2].mean()])
        normals, junctions, mirrored = [], [], []
        for region, loop in zip(topo.regions, _region_loops(cp, topo)):
            n = _newell_normal(loop)
            if n @ (loop.mean(axis=0) - centre_line) < 0:
                n = -n
            for sign in (np.ones(3), np.array([-1.0, 1.0, 1.0])):
                normals.append(n * sign)
                junctions.append(set(topo.region_junctions(region)))
                mirrored.append(sign[0] < 0)
        slots = list(keypoint_slots(topo).values())
        self.names = [s.name for s in slots]
        self.normals = np.array(normals)
        self.owner = np.zeros((len(slots), len(normals)), dtype=bool)
        for i, slot in enumerate(slots):
            junction = _junction_of(slot, topo)
            central = junction in topo.symmetry_junctions
            for r, (js, mirror) in enumerate(zip(junctions, mirrored)):
                self.owner[i, r] = (central or mirror == slot.is_mirror) and junction in js

    def facing(self, azimuth, elevation, margin_deg: float = 0.0) -> np.ndarray:
        """(70, V) bool: whether each keypoint lies on a region facing each of V views (azimuths
        and elevations in degrees, broadcast together), or facing a view up to ``margin_deg``
        away (the facing cone widened by that angle)."""
        t, p = np.broadcast_arrays(np.radians(np.asarray(azimuth, dtype=float)),
                                   np.radians(np.asarray(elevation, dtype=float)))
        d = np.stack([np.sin(t) * np.cos(p), -np.cos(t) * np.cos(p), np.sin(p)], axis=-1).reshape(-1, 3)
        level = np.cos(np.arccos(FACING_COS) + np.radians(margin_deg))
        faces = (self.normals @ d.T > level).astype(float)
        return self.owner.astype(float) @ faces > 0


def _junction_of(slot: KeypointSlot, topo: Topology) -> str:
    """The junction name of a slot (mirror names drop their suffix)."""
    return topo.keypoints[slot.keypoint_id - 1].name


def visible_slots(view: View, control_points: np.ndarray | None = None,
                  topology: Topology | None = None) -> list[KeypointSlot]:
    """:func:`visible_keypoints` as slots."""
    slots = keypoint_slots(topology)
    return [slots[n] for n in visible_keypoints(view, control_points, topology)]
