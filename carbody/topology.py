"""The wireframe topology: curves, junctions, keypoints and regions, read from one data file.

Everything that needs an index of a curve, a keypoint or a region reads it from here; nothing else
holds a hand-typed list. The data file is ``carbody/data/topology.json``.
"""
from __future__ import annotations

import functools

import json
from dataclasses import dataclass
from functools import cache
from importlib import resources

import numpy as np

from carbody.errors import TopologyError

#: Control points per cubic Bezier curve.
POINTS_PER_CURVE = 4


@dataclass(frozen=True)
class Curve:
    """One cubic Bezier curve of the left half, running from junction ``start`` to ``end``."""

    index: int
    name: str
    start: str
    end: str


@dataclass(frozen=True)
class Keypoint:
    """A named junction a person can mark on a photo (``id`` 1..35 as in the paper's Fig. 6)."""

    id: int
    name: str
    description: str
    on_symmetry_plane: bool

    @property
    def mirror_name(self) -> str | None:
        """Name of the right-half twin, or None for a point on the symmetry plane."""
        return None if self.on_symmetry_plane else f"{self.name}_right"


@dataclass(frozen=True)
class Region:
    """A closed loop of curves; ``loop`` holds (curve index, reversed) in loop order."""

    name: str
    description: str
    loop: tuple[tuple[int, bool], ...]
    ends: tuple[int, int]


@dataclass(frozen=True)
class Topology:
    """The whole wireframe topology (see module docstring)."""

    curves: tuple[Curve, ...]
    junctions: tuple[str, ...]
    symmetry_junctions: frozenset[str]
    keypoints: tuple[Keypoint, ...]
    regions: tuple[Region, ...]
    wheel_centres: dict[str, tuple[str, str]]
    overhang_boundaries: dict[str, str]

    @property
    def n_curves(self) -> int:
        return len(self.curves)

    @property
    def n_points(self) -> int:
        """Number of control points of the left half (70 curves x 4 = 280)."""
        return self.n_curves * POINTS_PER_CURVE

    def curve(self, name: str) -> Curve:
        for c in self.curves:
            if c.name == name:
                return c
        raise TopologyError(f"unknown curve {name!r}")

    def region(self, name: str) -> Region:
        for r in self.regions:
            if r.name == name:
                return r
        raise TopologyError(f"unknown region {name!r}")

    def junction_point_index(self, junction: str) -> int:
        """Index into the (280, 3) control-point array of one control point lying on ``junction``."""
        for c in self.curves:
            if c.start == junction:
                return c.index * POINTS_PER_CURVE
            if c.end == junction:
                return c.index * POINTS_PER_CURVE + POINTS_PER_CURVE - 1
        raise TopologyError(f"unknown junction {junction!r}")

    @functools.cached_property
    def keypoint_point_indices(self) -> np.ndarray:
        """(35,) int: control-point index of each keypoint, in keypoint order (computed once,
        read-only)."""
        out = np.array([self.junction_point_index(k.name) for k in self.keypoints])
        out.setflags(write=False)
        return out

    def junction_groups(self) -> dict[str, list[int]]:
        """Every control-point index lying on each junction (curve ends that must coincide)."""
        groups: dict[str, list[int]] = {j: [] for j in self.junctions}
        for c in self.curves:
            groups[c.start].append(c.index * POINTS_PER_CURVE)
            groups[c.end].append(c.index * POINTS_PER_CURVE + POINTS_PER_CURVE - 1)
        return groups

    def region_junctions(self, region: Region) -> list[str]:
        """The junctions met walking once round ``region``'s loop, in order."""
        out = []
        for ci, rev in region.loop:
            c = self.curves[ci]
            out.append(c.end if rev else c.start)
        return out


def _parse(data: dict) -> Topology:
    symmetry = frozenset(j["name"] for j in data["junctions"] if j["on_symmetry_plane"])
    junctions = tuple(j["name"] for j in data["junctions"])
    curves = tuple(Curve(i, c["name"], c["start"], c["end"]) for i, c in enumerate(data["curves"]))
    by_name = {c.name: c.index for c in curves}

    def curve_index(name: str) -> int:
        try:
            return by_name[name]
        except KeyError:
            raise TopologyError(f"region refers to unknown curve {name!r}") from None

    regions = tuple(
        Region(
            r["name"],
            r["description"],
            tuple((curve_index(n.lstrip("-")), n.startswith("-")) for n in r["loop"]),
            (curve_index(r["ends"][0]), curve_index(r["ends"][1])),
        )
        for r in data["regions"]
    )
    keypoints = tuple(
        Keypoint(k["id"], k["name"], k["description"], k["name"] in symmetry) for k in data["keypoints"]
    )
    return Topology(
        curves=curves,
        junctions=junctions,
        symmetry_junctions=symmetry,
        keypoints=keypoints,
        regions=regions,
        wheel_centres={k: tuple(v) for k, v in data["wheel_centres"].items()},
        overhang_boundaries=dict(data["overhang_boundaries"]),
    )


@cache
def load_topology() -> Topology:
    """The project's wireframe topology (parsed once per process)."""
    text = resources.files("carbody.data").joinpath("topology.json").read_text()
    return _parse(json.loads(text))
