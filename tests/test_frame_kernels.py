"""Stop 48's faster pieces of the intersection's frame kernel, each against
the code it replaced: the box's collision pairs found within a bound, from
the rows' order along ``x`` kept between frames
(:func:`~icv_envs.sim._kernels.intersection.box_pairs_ordered`), against
the two sweeps (``_box_pairs_sweeps``, itself tested against the array code
in ``tests/test_kernels.py``); and the PET update's candidates merged from
two ascending lists (:func:`~icv_envs.sim._kernels.stats.pet_transitions`),
against the sort and search it replaced (a copy of it below)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from icv_envs.sim._kernels.intersection import _box_pairs_sweeps, box_collision_pairs_cs, box_pairs_ordered
from icv_envs.sim._kernels.stats import pet_transitions


def _fleet(rng, n, span, dense, grid):
    """Vehicles on the four legs and in a 16 m box; ``dense`` packs them
    (many overlapping pairs), ``grid`` rounds positions and sizes (exact
    ties along both axes, touching bodies) and sets some headings exactly."""
    cx, cy = rng.uniform(-span, span, n), rng.uniform(-span, span, n)
    axis = rng.random(n) < 0.5
    cx[axis] = rng.uniform(-12.0, 12.0, int(axis.sum()))
    if dense:
        cx, cy = 0.2 * cx, 0.2 * cy
    heading = rng.choice([0.0, 0.5 * np.pi, np.pi, -0.5 * np.pi], n) + rng.normal(0, 0.3, n) * rng.integers(0, 2, n)
    length, width = rng.uniform(3.0, 12.0, n), rng.uniform(1.5, 2.6, n)
    if grid:
        cx, cy, length, width = np.round(cx), np.round(cy), np.round(length), np.round(width)
    ch = np.array([math.cos(h) for h in heading])
    sh = np.array([math.sin(h) for h in heading])
    return cx, cy, heading, ch, sh, length, width


@settings(max_examples=400, deadline=None)
@given(n=st.integers(0, 90), span=st.floats(12.0, 200.0), seed=st.integers(0, 2**31), dense=st.booleans(),
       grid=st.booleans(), start=st.sampled_from(["sorted", "shuffled", "reversed"]),
       bad=st.sampled_from([None, "nan_x", "inf_y", "nan_heading", "inf_length"]))
def test_box_pairs_within_the_bound_equal_the_two_sweeps(n, span, seed, dense, grid, start, bad):
    """The same pairs (values, dtype, order) as the two sweeps, from any
    starting order of the rows (sorted as the frames keep it, shuffled,
    reversed), which comes back sorted along ``x`` (NumPy's stable order);
    a non-finite value
    takes the sweeps themselves."""
    rng = np.random.default_rng(seed)
    cx, cy, heading, ch, sh, length, width = _fleet(rng, n, span, dense, grid)
    if bad and n:
        k = int(rng.integers(0, n))
        {"nan_x": cx, "inf_y": cy, "nan_heading": heading, "inf_length": length}[bad][k] = \
            np.nan if bad.startswith("nan") else np.inf
    want = _box_pairs_sweeps(cx, cy, heading, ch, sh, length, width, 16.0) if n >= 2 else \
        (np.zeros(0, dtype=np.int64),) * 2
    order = {"sorted": np.argsort(cx, kind="stable"), "shuffled": rng.permutation(n),
             "reversed": np.arange(n)[::-1].copy()}[start].astype(np.int64)
    *got, order = box_pairs_ordered(cx, cy, heading, ch, sh, length, width, 16.0, order)
    for g, w in zip(got, want):
        assert g.dtype == w.dtype and g.shape == w.shape and np.array_equal(g, w)
    for g, w in zip(box_collision_pairs_cs(cx, cy, heading, ch, sh, length, width, 16.0), want):
        assert np.array_equal(g, w)
    if n >= 2 and not bad:
        assert np.all(np.diff(cx[order]) >= 0)  # (sorted along x, for the next frame)
        assert np.array_equal(order, np.argsort(cx, kind="mergesort"))


def test_box_pairs_find_overlaps_on_both_axes():
    """Not vacuous: dense fleets give many pairs, from both sweeps (bodies
    on the north-south legs are found only by the sweep along ``y``)."""
    rng = np.random.default_rng(7)
    total = 0
    for _ in range(50):
        cx, cy, heading, ch, sh, length, width = _fleet(rng, 60, 60.0, True, False)
        i, j = box_collision_pairs_cs(cx, cy, heading, ch, sh, length, width, 16.0)
        total += len(i)
    assert total > 500
    # two vehicles queued on the north leg, one 4 m behind the other, 5 m long: a pair
    cx, cy = np.array([1.75, 1.75]), np.array([40.0, 44.0])
    heading = np.array([-0.5 * np.pi, -0.5 * np.pi])
    ch, sh = np.array([math.cos(h) for h in heading]), np.array([math.sin(h) for h in heading])
    i, j = box_collision_pairs_cs(cx, cy, heading, ch, sh, np.full(2, 5.0), np.full(2, 2.0), 16.0)
    assert i.tolist() == [0] and j.tolist() == [1]


def _pet_reference(vid, pid, s, length, lo, hi, occ, path, busy):
    """``pet_transitions`` as written until stop 47 (the candidates sorted
    by ``np.unique``, each listed vehicle's found by ``searchsorted``)."""
    P, K = lo.shape
    keep = [i for i in range(len(vid)) if pid[i] < P]
    cand = np.unique(np.concatenate([vid[keep], busy]).astype(np.int64))
    C = len(cand)
    new = np.zeros((C, K), dtype=bool)
    for i in keep:
        c = np.searchsorted(cand, vid[i])
        x, h, p = s[i], 0.5 * length[i], pid[i]
        for k in range(K):
            new[c, k] = (x - h < hi[p, k]) and (x + h > lo[p, k])
    prev = path[cand].copy()
    for i in keep:
        path[vid[i]] = pid[i]
    left, entered, nb = [], [], []
    for c in range(C):
        v = cand[c]
        for k in range(K):
            o = occ[v, k]
            if o and not new[c, k]:
                left.append((prev[c], k))
            elif new[c, k] and not o:
                entered.append((path[v], k))
            occ[v, k] = new[c, k]
        if new[c].any():
            nb.append(v)
    return (np.array(left, dtype=np.int64).reshape(-1, 2), np.array(entered, dtype=np.int64).reshape(-1, 2),
            np.array(nb, dtype=np.int64))


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**31), order=st.sampled_from(["ascending", "shuffled", "duplicates"]))
def test_pet_candidates_merged_equal_the_sort_and_search(seed, order):
    """Over a sequence of updates, the slots left and entered, the new busy
    list and both tables equal the replaced code's; with the listed ids
    ascending (the fleet's rows; the merge), shuffled or repeated (the
    sort and search)."""
    rng = np.random.default_rng(seed)
    P, K, n_ids = 6, 4, 40
    lo = np.sort(rng.uniform(-5.0, 30.0, (P, K)), axis=1)
    hi = lo + rng.uniform(1.0, 6.0, (P, K))
    states = [(np.zeros((n_ids, K), dtype=np.bool_), np.full(n_ids, -1, dtype=np.int64), np.zeros(0, dtype=np.int64))
              for _ in range(2)]
    pos = rng.uniform(-20.0, 10.0, n_ids)
    paths = rng.integers(0, P + 1, n_ids)  # P: a path without areas (skipped)
    for _ in range(30):
        pos = pos + rng.uniform(0.0, 3.0, n_ids)
        vid = np.flatnonzero(rng.random(n_ids) < 0.7).astype(np.int64)
        if order == "shuffled":
            vid = rng.permutation(vid)
        elif order == "duplicates" and len(vid):
            vid = np.sort(np.concatenate([vid, vid[:2]]))
        args = (vid, paths[vid], pos[vid], np.full(len(vid), 4.5), lo, hi)
        outs = []
        for k, fn in enumerate((pet_transitions, _pet_reference)):
            occ, path, busy = states[k]
            left, entered, busy = fn(*args, occ, path, busy)
            states[k] = (occ, path, busy)
            outs.append((left, entered, busy))
        for g, w in zip(*outs):
            assert np.array_equal(g, w) and g.dtype == w.dtype
        for g, w in zip(*states):
            assert np.array_equal(g, w)
        if rng.random() < 0.2:
            paths[rng.integers(0, n_ids)] = rng.integers(0, P)


@settings(max_examples=300, deadline=None)
@given(n=st.integers(0, 60), seed=st.integers(0, 2**31), ties=st.booleans(),
       special=st.sampled_from([None, "nan", "inf", "-inf", "zeros"]), start=st.sampled_from(["sorted", "shuffled"]))
def test_stable_order_is_numpys_mergesort(n, seed, ties, special, start):
    """The insertion sort from any permutation gives ``np.argsort(x,
    kind="mergesort")`` exactly: ties by index, ``-0.0`` equal to ``0.0``,
    infinities in place, NaN (NumPy's sort) last."""
    from icv_envs.sim._kernels.neighbours import stable_order

    rng = np.random.default_rng(seed)
    x = rng.uniform(-50.0, 50.0, n)
    if ties:
        x = np.round(x / 10.0) * 10.0
    if special and n:
        k = rng.integers(0, n, max(1, n // 5))
        x[k] = {"nan": np.nan, "inf": np.inf, "-inf": -np.inf, "zeros": -0.0}[special]
        if special == "zeros":
            x[rng.integers(0, n, max(1, n // 5))] = 0.0
    order = (np.argsort(x, kind="mergesort") if start == "sorted" else rng.permutation(n)).astype(np.int64)
    got = stable_order(x, order.copy())
    assert np.array_equal(got, np.argsort(x, kind="mergesort"))
    # a wrong length (another frame's rows): NumPy's sort
    assert np.array_equal(stable_order(x, np.zeros(max(0, n - 1), dtype=np.int64)), np.argsort(x, kind="mergesort"))


@settings(max_examples=200, deadline=None)
@given(n=st.integers(0, 80), span=st.floats(5.0, 400.0), periodic=st.booleans(), seed=st.integers(0, 2**31),
       frames=st.integers(1, 6))
def test_collision_pairs_kept_from_frame_to_frame_equal_the_sweep(n, span, periodic, seed, frames):
    """Frames of moving, dense traffic (vehicles overtaking, crossing a
    ring's seam, so the ghosts change): the pairs found with the order and
    ghosts kept from the frame before equal those of a fresh sweep, in the
    same order, at every frame."""
    from icv_envs.sim._kernels.neighbours import collision_pairs_cs, collision_pairs_kept

    rng = np.random.default_rng(seed)
    cx = rng.uniform(0, span, n)
    cy = rng.integers(0, 3, n) * 4.0 + rng.normal(0, 1.2, n)
    v = rng.uniform(0.0, 30.0, n)
    L, W = rng.uniform(4, 6, n), rng.uniform(1.8, 2.2, n)
    period = span if periodic else -1.0
    order = ghosts = np.zeros(0, dtype=np.int64)
    for _ in range(frames):
        cx = cx + v * 0.4
        if periodic:
            cx = np.mod(cx, span)
        h = rng.normal(0, 0.2, n)
        ch = np.array([math.cos(t) for t in h])
        sh = np.array([math.sin(t) for t in h])
        i, j, order, ghosts = collision_pairs_kept(cx, cy, ch, sh, L, W, period, order, ghosts)
        wi, wj = collision_pairs_cs(cx, cy, ch, sh, L, W, period)
        assert np.array_equal(i, wi) and np.array_equal(j, wj)
