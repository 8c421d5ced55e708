"""Per-vehicle episodes on the slot layout (icv_envs.rl.slots.VehicleEpisodes)."""

import numpy as np
import pytest

from icv_envs.rl.slots import SlotParallelEnv, VehicleEpisodes, vehicle_slots_env

CFG = {"throughput": 2500, "duration": 60, "warmup": 60}


def _run(env, steps, policy="expert"):
    """Drive every slot agent by its expert label; return per-slot vehicle sequences and transitions."""
    obs, infos = env.reset(seed=3)
    seen = {s: [infos[s]["vehicle"]] for s in env.agents}
    trans = []
    for _ in range(steps):
        if env.episode_over:
            break
        acts = {s: infos[s]["expert_action"] for s in env.agents}
        before = list(env.agents)
        obs, rew, term, trunc, infos = env.step(acts)
        trans.append((before, obs, term, trunc, infos))
        for s in obs:
            seen.setdefault(s, []).append(infos[s]["vehicle"])
    return seen, trans


def test_agents_are_the_slots_with_a_live_vehicle_and_episodes_follow_vehicles():
    env = vehicle_slots_env("intersection_v0", CFG)
    assert env.possible_agents == [f"slot_{i}" for i in range(env.slot_env.K)]
    seen, trans = _run(env, 400)
    ended = 0
    for before, obs, term, trunc, infos in trans:
        for s in before:  # every agent that acted reports its transition
            assert s in obs
        for s in obs:
            done = term[s] or trunc[s]
            if s in before:
                assert done == (infos[s]["vehicle_done"] or (trunc[s] and not term[s]))
                ended += done
            else:  # a new vehicle in a freed slot: an episode start, never a done
                assert infos[s]["active"] and not term[s]
            assert not (term[s] and trunc[s])
            assert obs[s].shape == env.observation_space(s).shape
        # a slot whose vehicle ended is not an agent until the next vehicle takes it
        for s in obs:
            if s in before and (term[s] or trunc[s]):
                assert s not in env.agents
    assert ended > 10
    # slots are reused: some slot carried more than one vehicle, each vehicle in one run of steps
    assert any(len(set(v)) > 1 for v in seen.values())
    for v in seen.values():
        runs = [a for i, a in enumerate(v) if i == 0 or a != v[i - 1]]
        assert len(runs) == len(set(runs)), "a vehicle came back to a slot after another one"


def test_expert_through_the_adapter_has_no_crash_and_the_vec_env_has_few_placeholders():
    pytest.importorskip("stable_baselines3")
    from icv_envs.rl.vec_env import ParallelVecEnv

    v = ParallelVecEnv(lambda: vehicle_slots_env("intersection_v0", CFG), seed=0)
    v.reset()
    infos = [{} for _ in range(v.num_envs)]
    crashed = episodes = 0
    for _ in range(300):
        acts = np.stack([np.asarray(i.get("expert_action", np.zeros(2)), dtype=np.float32) for i in infos])
        # the label of the next action is in the infos of the last step (or the reset infos)
        for k in range(v.num_envs):
            if v.active[k] and "expert_action" not in infos[k]:
                acts[k] = v.reset_infos[k].get("expert_action", np.zeros(2))
        _o, _r, _d, infos = v.step(acts)
        for i in infos:
            if "episode" in i:
                episodes += 1
                crashed += bool(i.get("crashed", False))
    assert episodes > 10 and crashed == 0
    assert v.placeholder_fraction < 0.5  # one slot per possible arrival: 0.98-0.99 (issue 9)


def test_needs_a_slot_env():
    with pytest.raises(TypeError, match="SlotParallelEnv"):
        VehicleEpisodes(object())
    assert isinstance(vehicle_slots_env("intersection_v0", CFG).slot_env, SlotParallelEnv)
