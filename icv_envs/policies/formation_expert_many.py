"""The formation expert of several worlds in one pass (issue 10, from stop 46).

:class:`icv_envs.vector.BatchedWorlds` asks the expert of every world each
step. Called world by world, :meth:`FormationExpert.compute
<icv_envs.policies.formation_expert.FormationExpert.compute>` spends most of
its time in the Python around its kernels (about 35 of 55 us on a
20-vehicle world), not in them. :func:`compute_many` runs ``compute`` once
for many worlds: their state arrays concatenated, the passes that treat
each vehicle on its own (desired lanes, the lane-change curves, preview
points, pure pursuit, the lane speeds; and NumPy's transcendental calls
between them, whose results do not depend on an element's place in the
array) run on the concatenated arrays, and the two passes that read a
world's lane index (which lane changes start; the longitudinal law with
its safety envelope) run world by world inside one compiled call
(:mod:`icv_envs.policies._kernels.many_worlds`). Every world gets exactly
the actions and the lane-change state ``compute`` gives it alone, bit for
bit (``tests/test_expert_many.py``).

Worlds are computed together when their experts are plain
:class:`~icv_envs.policies.formation_expert.FormationExpert` (no hook
replaced) with equal parameters on roads with equal geometry; any other
world is computed alone, by its own expert.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from icv_envs._hooks import own_hooks
from icv_envs._ufuncs import flatnonzero
from icv_envs.formation.bezier import _lane_change_lateral_rows, _pure_pursuit_rows
from icv_envs.policies._kernels import desired_lane_rows, free_speed_pow_rows, lane_changes_ended, preview_points
from icv_envs.policies._kernels.many_worlds import expert_control_many, lane_change_starts_many
from icv_envs.policies.formation_expert import _HEAD_HOOKS, _TAIL_HOOKS, FormationExpert

__all__ = ["compute_many"]

# The groups' keys by value -> a tag, the same int for equal keys (from stop 48: the key, a tuple of
# about 80 parts, was hashed and compared with another world's equal key by value for every world and
# step, about 3.4 us a world). A tag is never given twice (the counter only grows), so forgetting the
# table when it is large only parts worlds that could share a pass, never joins worlds that cannot.
_TAGS: dict = {}
_NEXT_TAG = itertools.count()
_MAX_TAGS = 4096

_LC = ("lc_lane", "lc_x0", "lc_y0", "lc_y1", "lc_len")  # the expert's memory in the traffic arrays


def compute_many(experts: list, worlds: list, dtype=np.float64) -> list[np.ndarray]:
    """``[experts[i].compute(worlds[i]).astype(dtype) for i ...]``, the same
    numbers and the same changes to each world's lane-change state bit for
    bit, with the worlds that can be computed together (module docstring)
    computed in one pass. The arrays of one pass are row views of one
    array. The worlds must be distinct objects."""
    if len(experts) != len(worlds):
        raise ValueError(f"{len(experts)} experts for {len(worlds)} worlds; allowed: one expert per world")
    if len(set(map(id, worlds))) != len(worlds):
        # (a world asked twice in one pass would be computed twice from the same state, where asking it
        # twice in turn computes the second time from the plans the first one changed)
        first = {}
        dup = next(i for i, w in enumerate(worlds) if first.setdefault(id(w), i) != i)
        raise ValueError(f"worlds[{dup}] is worlds[{first[id(worlds[dup])]}]; allowed: distinct worlds")
    out: list = [None] * len(worlds)
    groups: dict = {}  # (a world that can share no pass is a group of its own, keyed by its place)
    for i, (e, w) in enumerate(zip(experts, worlds)):
        key = _group_key(e, w)
        groups.setdefault(("alone", i) if key is None else key, []).append(i)
    for rows in groups.values():
        if len(rows) == 1:  # alone: its own expert
            i = rows[0]
            out[i] = experts[i].compute(worlds[i]).astype(dtype)
            continue
        acts, offs = _compute_group([experts[i] for i in rows], [worlds[i] for i in rows])
        acts = acts.astype(dtype, copy=False)
        for k, i in enumerate(rows):
            out[i] = acts[offs[k]:offs[k + 1]]
    return out


def _group_key(expert, world):
    """What a world's expert and road must share with another's to be
    computed with it (the expert's parameters and every road constant its
    kernels read, by value), as a tag (an int, the same for equal keys:
    ``_TAGS``), or None when its expert is not a plain
    :class:`FormationExpert` or it has no vehicles. Made once per road (a
    reset builds a new one)."""
    if type(expert) is not FormationExpert or not (own_hooks(expert, _HEAD_HOOKS) and own_hooks(expert, _TAIL_HOOKS)):
        return None
    if not world.traffic.n:
        return None
    road = world.road
    kept = expert.__dict__.get("_many_key")
    if kept is not None and kept[0] is road:
        return kept[1]
    consts = expert._road_consts(road)
    parts = [type(road).__qualname__, repr(dataclasses.astuple(expert.p)), repr(float(road.lane_width)),
             repr(int(road.total_lanes))]
    for name in sorted(consts):
        for v in consts[name]:
            if isinstance(v, np.ndarray):
                parts.append((v.dtype.str, v.shape, v.tobytes()))
            else:
                parts.append(repr(v))
    key = tuple(parts)
    if len(_TAGS) >= _MAX_TAGS:
        _TAGS.clear()
    tag = _TAGS.get(key)
    if tag is None:
        tag = _TAGS[key] = next(_NEXT_TAG)
    expert._many_key = (road, tag)
    return tag


def _cat(arrays: list) -> np.ndarray:
    """The arrays concatenated, read-only when the first is (as the state
    arrays mostly are: the kernels then see the types they were compiled
    for)."""
    out = np.concatenate(arrays)
    if not arrays[0].flags.writeable:
        out.flags.writeable = False
    return out


def _compute_group(experts: list, worlds: list) -> tuple[np.ndarray, np.ndarray]:
    """``FormationExpert.compute`` of worlds of one group (each with
    vehicles), its steps in its order over the concatenated arrays; returns
    the ``(n, 2)`` float64 actions of all rows and the rows' offsets per
    world. Writes the lane-change state back into the worlds that changed."""
    e0 = experts[0]
    p = e0.p
    road = worlds[0].road
    c = e0._road_consts(road)
    trs = [w.traffic for w in worlds]
    offs = np.zeros(len(trs) + 1, dtype=np.int64)
    np.cumsum([tr.n for tr in trs], out=offs[1:])
    centres = [tr.center() for tr in trs]
    cx, cy = _cat([a for a, _ in centres]), _cat([b for _, b in centres])
    x, y, heading, v = (_cat([getattr(tr, k) for tr in trs]) for k in ("x", "y", "heading", "speed"))
    length = np.concatenate([np.asarray(tr.length, dtype=np.float64) for tr in trs])
    lc_lane, lc_x0, lc_y0, lc_y1, lc_len = (np.concatenate([getattr(tr, k) for tr in trs]) for k in _LC)
    lc_before = lc_lane.copy()  # (to find the worlds whose state changed)
    exit_id = _cat([tr.exit for tr in trs])
    cos_sin = [tr.heading_cos_sin() for tr in trs]
    cos, sin = _cat([a for a, _ in cos_sin]), _cat([b for _, b in cos_sin])
    # each world's lane index, its own row numbers (the kernels cut it per world)
    idx = [w.lane_index() for w in worlds]
    ioffs = np.zeros(len(idx) + 1, dtype=np.int64)
    np.cumsum([ix.keys.shape[0] for ix in idx], out=ioffs[1:])
    keys, i_rows, i_lanes, i_x = (_cat([getattr(ix, k) for ix in idx]) for k in ("keys", "rows", "lanes", "x"))
    i_offset = np.array([float(ix.offset) for ix in idx])
    refs = [w.manager.references(tr) for w, tr in zip(worlds, trs)]
    x_ref, lane_ref, v_ref, member = (_cat([r[k] for r in refs]) for k in range(4))
    member = np.asarray(member, dtype=bool)
    lane_ref = np.asarray(lane_ref, dtype=np.int64)
    W = road.lane_width
    lane = np.asarray(road.lane_of_rows(cy), dtype=np.int64)

    # the desired lanes (FormationExpert.compute's one-call path: its hooks are its own)
    desired, exiting = desired_lane_rows(member, lane_ref, lane, exit_id, cx, *c["exit"], cx, *c["escape"])
    # lane changes that ended or strayed, then those that start (world by world: the gaps)
    active = lc_lane >= 0
    if np.count_nonzero(active):
        a_rows = flatnonzero(active)
        y_plan, _ = _lane_change_lateral_rows(a_rows, x, lc_x0, lc_y0, lc_y1, lc_len)
        lane_changes_ended(a_rows, y_plan, x, y, cy, v, lc_x0, lc_len, lc_y1, lc_lane, float(p.replan_tolerance))
        active = lc_lane >= 0
    ended = lc_lane != lc_before  # (a lane change that ends here may start again in the same lane below)
    start, s_lane, s_len, blocked = lane_change_starts_many(offs, ioffs, i_offset, active, cx, cy, v, length, lane,
                                                            desired, member, keys, i_rows, i_lanes, i_x, *c["starts"])
    if len(start):
        lc_lane[start] = s_lane
        lc_x0[start] = x[start]
        lc_y0[start] = y[start]
        lc_y1[start] = s_lane * W
        lc_len[start] = s_len
        active = lc_lane >= 0
    # steering
    px, py = preview_points(x, v, lane, float(W), float(p.preview_min), float(p.preview_time))
    if np.count_nonzero(active):
        a_rows = flatnonzero(active)
        py[a_rows] = _lane_change_lateral_rows(a_rows, px, lc_x0, lc_y0, lc_y1, lc_len)[0]
    phi = _pure_pursuit_rows(x, y, heading, px, py, float(p.wheelbase), float(p.steer_max), (cos, sin))
    # longitudinal law, safety envelope, normalised actions (world by world: the leaders)
    free_rows = flatnonzero(~member)
    m = flatnonzero(member)
    a_ref = np.concatenate([w.manager.reference_accel(tr) for w, tr in zip(worlds, trs)])
    free_pow = free_speed_pow_rows(*e0._lane_speed_args(road, lane), *e0._lane_target_args(road, exiting, blocked,
                                                                                           member),
                                   free_rows, v)
    acts = expert_control_many(offs, np.searchsorted(free_rows, offs), np.searchsorted(m, offs), ioffs, i_offset,
                               free_rows, free_pow, v, c["idm"], m, cx, np.asarray(x_ref, dtype=np.float64),
                               np.asarray(v_ref, dtype=np.float64), np.asarray(a_ref, dtype=np.float64),
                               c["feedback"], keys, i_rows, i_lanes, i_x, length, lc_lane, lane, desired, member,
                               exiting, c["safety"], np.asarray(phi, dtype=np.float64), e0._normalise_args())
    # the lane-change state back into the worlds whose state changed (in place, as compute writes it)
    ended[start] = True
    changed = flatnonzero(ended)
    if len(changed):
        for b in np.unique(np.searchsorted(offs, changed, side="right") - 1).tolist():
            o0, o1 = offs[b], offs[b + 1]
            tr = trs[b]
            for k, arr in zip(_LC, (lc_lane, lc_x0, lc_y0, lc_y1, lc_len)):
                getattr(tr, k)[:] = arr[o0:o1]
    return acts, offs
