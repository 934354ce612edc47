"""The wireframe topology: 70 cubic curves, 35 keypoints, 13 closed regions, one connected net."""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components


def test_counts_match_the_paper(topology):
    assert topology.n_curves == 70
    assert topology.n_points == 280
    assert len(topology.keypoints) == 35
    assert len(topology.regions) == 13
    assert [k.id for k in topology.keypoints] == list(range(1, 36))


def test_names_are_unique(topology):
    for names in ([c.name for c in topology.curves], list(topology.junctions),
                  [k.name for k in topology.keypoints], [r.name for r in topology.regions]):
        assert len(names) == len(set(names))
    mirrors = [k.mirror_name for k in topology.keypoints if k.mirror_name]
    assert not set(mirrors) & {k.name for k in topology.keypoints}


def test_every_keypoint_is_a_junction_with_a_description(topology):
    ends = {c.start for c in topology.curves} | {c.end for c in topology.curves}
    for k in topology.keypoints:
        assert k.name in ends
        assert len(k.description) > 15


def test_every_region_loop_closes(topology):
    for region in topology.regions:
        walk = []
        for ci, rev in region.loop:
            c = topology.curves[ci]
            walk.append((c.end, c.start) if rev else (c.start, c.end))
        for (_, end), (start, _) in zip(walk, walk[1:] + walk[:1]):
            assert end == start, f"{region.name} breaks between {end} and {start}"
        loop_curves = {ci for ci, _ in region.loop}
        assert set(region.ends) <= loop_curves, region.name


def test_the_network_is_connected(topology):
    index = {j: i for i, j in enumerate(topology.junctions)}
    rows = [index[c.start] for c in topology.curves]
    cols = [index[c.end] for c in topology.curves]
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(index),) * 2)
    n, _ = connected_components(graph, directed=False)
    assert n == 1


def test_regions_tile_the_half_body(topology):
    """Each curve bounds two regions, or one when it lies on the symmetry plane or the
    body's lower opening; the half body is a disc (V - E + F = 1)."""
    uses = np.zeros(topology.n_curves, int)
    for region in topology.regions:
        for ci, _ in region.loop:
            uses[ci] += 1
    assert set(uses) <= {1, 2}
    once = {topology.curves[i].name for i in np.flatnonzero(uses == 1)}
    on_plane = {c.name for c in topology.curves
                if c.start in topology.symmetry_junctions and c.end in topology.symmetry_junctions}
    assert on_plane <= once
    opening = once - on_plane
    assert {"sill_bottom_1", "front_arch_1", "rear_arch_4", "front_bottom_1", "rear_bottom_1"} <= opening
    assert len(topology.junctions) - topology.n_curves + len(topology.regions) == 1


def test_keypoint_indices_point_at_their_junction(topology):
    idx = topology.keypoint_point_indices
    assert idx.shape == (35,)
    for k, i in zip(topology.keypoints, idx):
        c = topology.curves[i // 4]
        assert k.name == (c.start if i % 4 == 0 else c.end)
