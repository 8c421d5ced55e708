"""The virtual platoon's order repair (compiled:
:func:`icv_envs.policies._kernels.repair_order`, called by
:meth:`VirtualPlatoon.tree` through ``vp_tree``; until stop 40 through
``VirtualPlatoon._repair_order``) against the pure-Python loop it replaced,
on random nodes, and on one hand-built case."""

import types

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from icv_envs.policies._kernels import repair_order


class _Fleet:
    def __init__(self, vid):
        self.vid = vid

    def rows(self, vids):
        return np.searchsorted(self.vid, np.asarray(vids, dtype=np.int64))


def _reference(nodes, leg_of, rs, order, rows_of):
    """The loop of the release before: per node and approach lane the nearest and farthest member;
    the first later node ``b`` (then earlier ``a``) of one leg with a vehicle ahead of a vehicle of
    ``a`` in a shared lane moves to ``a``'s place; restart."""
    lanes = {}
    for k in order:
        r = rows_of(nodes[k]["members"])
        r = r[rs.phase[r] == 0]
        lanes[k] = ({int(ln): float(rs.dist[r[rs.lane[r] == ln]].min()) for ln in np.unique(rs.lane[r])},
                    {int(ln): float(rs.dist[r[rs.lane[r] == ln]].max()) for ln in np.unique(rs.lane[r])})
    leg = {k: int(leg_of[nodes[k]["mv"]]) for k in order}
    order, moves = list(order), 0
    for _ in range(4 * len(order) + 4):
        hit = False
        for b in range(1, len(order)):
            k = order[b]
            for a in range(b):
                i = order[a]
                if leg[i] == leg[k] and any(ln in lanes[k][0] and lanes[k][0][ln] < lanes[i][1][ln] - 1e-6
                                            and lanes[k][0][ln] < lanes[i][0][ln] for ln in lanes[i][1]):
                    order.insert(a, order.pop(b))
                    hit = True
                    moves += 1
                    break
            if hit:
                break
        if not hit:
            break
    return order, moves


def _run(nodes, leg_of, rs, order, n):
    """The repair as ``VirtualPlatoon.tree`` runs it: the kernel on every
    node's member rows, the new order of the ids, then ``vp_order`` (the
    repaired order, the ids it does not hold after it)."""
    vid = np.arange(n, dtype=np.int64) * 3
    fleet = _Fleet(vid)
    ids = list(nodes)
    members = [nodes[k]["members"] for k in ids]
    seg = np.repeat(np.arange(len(ids)), [len(m) for m in members]).astype(np.int64)
    rows = fleet.rows(np.concatenate(members)).astype(np.int64)
    pos = {k: i for i, k in enumerate(ids)}
    o = np.array([pos[k] for k in order], dtype=np.int64)
    mvs = np.array([nodes[k]["mv"] for k in ids], dtype=np.int64)
    at, moves = repair_order(o, len(ids), rows, seg, np.asarray(rs.phase, dtype=np.int64),
                             np.asarray(rs.lane, dtype=np.int64), np.asarray(rs.dist, dtype=np.float64),
                             np.asarray(leg_of)[mvs])
    new = [ids[i] for i in at]
    vp_order = new + [k for k in order if k not in set(new)]
    return new, moves, vp_order, fleet.rows


def test_a_node_with_a_vehicle_ahead_in_the_shared_lane_moves_first():
    # node 10 (vehicle at 80 m, lane 1) is ordered before node 11 (vehicle at 40 m, lane 1), same leg
    nodes = {10: {"mv": 0, "members": [0]}, 11: {"mv": 1, "members": [3]}}
    rs = types.SimpleNamespace(phase=np.zeros(2, dtype=np.int64), lane=np.array([1, 1]), dist=np.array([80.0, 40.0]))
    order, moves, vp_order, _ = _run(nodes, np.array([0, 0] + [1] * 10), rs, [10, 11], 2)
    assert order == [11, 10] and moves == 1 and vp_order == [11, 10]
    # another leg (movement 3 is on leg 1): no repair; another lane: no repair
    nodes[11]["mv"] = 3
    assert _run(nodes, np.array([0, 0, 0, 1] + [1] * 8), rs, [10, 11], 2)[:2] == ([10, 11], 0)
    nodes[11]["mv"] = 1
    rs.lane = np.array([0, 1])
    assert _run(nodes, np.array([0, 0] + [1] * 10), rs, [10, 11], 2)[:2] == ([10, 11], 0)


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_repair_matches_the_loop_it_replaced(data):
    n = data.draw(st.integers(1, 20))
    K = data.draw(st.integers(1, 7))
    node_of = data.draw(st.lists(st.integers(0, K - 1), min_size=n, max_size=n))
    nodes = {}
    for k in range(K):
        m = [3 * i for i in range(n) if node_of[i] == k]
        if m:
            perm = data.draw(st.permutations(m))
            nodes[k + 10] = {"mv": data.draw(st.integers(0, 11)), "members": list(perm)}
    dist = np.array(data.draw(st.lists(st.integers(0, 60), min_size=n, max_size=n)), dtype=np.float64)
    rs = types.SimpleNamespace(phase=np.array(data.draw(st.lists(st.sampled_from([0, 0, 0, 1]), min_size=n,
                                                                   max_size=n))),
                               lane=np.array(data.draw(st.lists(st.integers(0, 2), min_size=n, max_size=n))),
                               dist=dist * data.draw(st.sampled_from([1.0, 0.37])))
    leg_of = np.arange(12) // 3 if data.draw(st.booleans()) else np.zeros(12, dtype=np.int64)
    order = list(data.draw(st.permutations(list(nodes))))
    got, moves, _, rows_of = _run(nodes, leg_of, rs, order, n)
    assert (got, moves) == _reference(nodes, leg_of, rs, order, rows_of)
