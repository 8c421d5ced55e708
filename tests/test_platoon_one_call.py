"""The intersection experts' one-call ``compute`` (stop 47,
``policies/_kernels.platoon_actions_rows``) against the separate calls it
stands for (``_steering``, ``_longitudinal``, ``_envelope``): the same
actions bit for bit and the same statistics, step by step, under multi-vp,
single-vp and FCFS (whose longitudinal law is its own), with vehicles held
standing in the box so that the path obstacles' fallback runs too."""

from __future__ import annotations

import numpy as np
import pytest

from icv_envs.envs.intersection_v0 import parallel_env
from icv_envs.policies._kernels import box_obstacle_rows


def _separate(ex, world):
    """``ex.compute(world)`` through the separate calls (the instance's
    ``_ONE_CALL_HOOKS`` None turns the one-call path off)."""
    ex._ONE_CALL_HOOKS = None
    try:
        return ex.compute(world)
    finally:
        del ex._ONE_CALL_HOOKS


def _twin_run(method: str, throughput: float, seed: int, steps: int, hold: float) -> tuple[int, int]:
    """Step an intersection with the expert's actions (the first vehicles
    reach the box after about 80 s: 380 steps without comparing first),
    then ``steps`` steps with a share ``hold`` of the vehicles in the box
    braking to a stand; at each of those the one-call and the separate
    compute of the same state must agree. Returns (steps compared, steps
    with a vehicle standing in the box)."""
    env = parallel_env(method=method, throughput=throughput, duration=(380 + steps) / 5.0 + 10.0,
                       expert_in_info=False)
    env.reset(seed=seed)
    core = env.core
    ex, w = core.expert, core.world
    for _ in range(380):
        env.step_rows(core.expert_actions())
    rng = np.random.default_rng(seed)
    held: set[int] = set()
    compared = standing = 0
    for _ in range(steps):
        f = w.fleet
        if not f.n:
            env.step_rows(np.zeros((0, 2), dtype=np.float32))
            continue
        rs = w.route()
        s0 = dict(ex.stats)
        one = ex.compute(w)
        s1 = dict(ex.stats)
        sep = _separate(ex, w)
        s2 = dict(ex.stats)
        assert one.dtype == sep.dtype and one.shape == sep.shape
        assert one.tobytes() == sep.tobytes(), f"{method} step {compared}: actions differ"
        # the counters grow by as much; a running maximum (FCFS's max_plan_error) is where the first left it
        assert set(s1) == set(s2)
        for k in s1:
            if isinstance(s1[k], (int, np.integer)):
                assert s1[k] - s0.get(k, 0) == s2[k] - s1[k], f"statistic {k} differs"
            else:
                assert s2[k] == s1[k], f"statistic {k} differs"
        compared += 1
        standing += bool(len(box_obstacle_rows(rs.phase, rs.s, rs.L, f.speed, 1.0)))
        acts = core.expert_actions().astype(np.float32)
        in_box = np.flatnonzero(rs.phase == 1)
        for r in in_box.tolist():
            v = int(f.vid[r])
            if v not in held and rng.random() < hold:
                held.add(v)
        for r in range(f.n):
            if int(f.vid[r]) in held:
                acts[r] = (-1.0, 0.0)
        env.step_rows(acts)
    return compared, standing


@pytest.mark.parametrize("method, throughput, seed", [("multi-vp", 2500.0, 1), ("single-vp", 2000.0, 2),
                                                      ("fcfs", 2500.0, 3)])
def test_one_call_compute_is_the_separate_calls(method, throughput, seed):
    compared, standing = _twin_run(method, throughput, seed, steps=250, hold=0.05)
    assert compared > 200
    assert standing > 20  # the fallback (vehicles standing in the box) ran too


def test_a_replaced_hook_is_honoured():
    """A hook the one-call path stands for, replaced on the instance, is
    called (the path is not taken): here a steering of zeros."""
    env = parallel_env(method="multi-vp", throughput=2200.0, duration=60.0, expert_in_info=False)
    env.reset(seed=0)
    core = env.core
    for _ in range(100):
        env.step_rows(core.expert_actions())
    ex, w = core.expert, core.world
    base = ex.compute(w)
    assert np.count_nonzero(base[:, 1])
    ex._steering = lambda world, rs: np.zeros(world.fleet.n)
    out = ex.compute(w)
    assert not np.count_nonzero(out[:, 1]) and np.array_equal(out[:, 0], base[:, 0])


def _state(env) -> bytes:
    """Everything the coordination layer holds and the fleet's arrays, as bytes."""
    core = env.core
    f, ex = core.world.fleet, core.expert
    parts = [repr(sorted(ex.stats.items())), repr(ex.formations), repr(ex.subs), repr(ex.nodes), repr(ex.vp_order)]
    parts += [f.vid.tobytes()] + [getattr(f, name).tobytes() for name in sorted(f._fields)]
    return b"".join(p.encode() if isinstance(p, str) else p for p in parts)


@pytest.mark.parametrize("method, throughput, seed", [("multi-vp", 3000.0, 4), ("multi-vp", 1800.0, 6),
                                                      ("single-vp", 2500.0, 5), ("fcfs", 2000.0, 7)])
def test_regroup_in_one_call_is_the_three_steps(method, throughput, seed):
    """``Regrouping._regroup`` (stop 47: approach and division, adjusting and
    merging with their kernels in one call) against the three separate
    steps (a hook set on the instance turns the one-call path off): the same
    fleet, groups, order and statistics after every step of two twin runs,
    divisions, adjustings and merges included."""
    envs = []
    for one_call in (True, False):
        env = parallel_env(method=method, throughput=throughput, duration=200.0, expert_in_info=False)
        env.reset(seed=seed)
        if not one_call:
            ex = env.core.expert
            ex._merging = ex._merging  # (an instance attribute among the hooks: the separate calls)
        envs.append(env)
    from icv_envs._hooks import own_hooks
    from icv_envs.policies.platoon_expert import _REGROUP_HOOKS

    assert [own_hooks(env.core.expert, _REGROUP_HOOKS) for env in envs] == [True, False]
    for k in range(800):
        for env in envs:
            env.step_rows(env.core.expert_actions())
        assert _state(envs[0]) == _state(envs[1]), f"{method} step {k}"
    st = envs[0].core.expert.stats
    assert st["divisions"] > 5 and envs[0].core.world.fleet.n > 10
    if method == "multi-vp" and throughput >= 3000:
        assert st["merges"] > 0
