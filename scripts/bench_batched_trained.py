"""The batched worlds' speed under a trained policy's actions (issue 10's
bar "batched highway formation worlds, 20 agents each, learned actions").

    PYTHONPATH=$PWD python scripts/bench_batched_trained.py [--model results/learned/bc_onramp]
        [--worlds 16] [--vehicles 20] [--steps 300] [--warmup 100] [--seed 0] [--out FILE]

Needs the ``rl`` extra (torch, stable-baselines3). Until stop 44 the
bar's "learned actions" were measured with zero actions (every vehicle
coasts, nothing crashes, the worlds stay full) and with an untrained
policy's uniform random actions (the worlds empty within seconds). Neither
is what a trained policy does: it drives its vehicles along their
formation references, as the expert does, and keeps them on the road.
Here every agent of :class:`icv_envs.vector.BatchedWorlds` (``--worlds``
HighwayFormation worlds of ``--vehicles`` agents, the worlds' default
free road) acts by one shared trained policy, a model written by
``baselines/bc_expert.py`` or ``ppo_shared.py`` for the multi-agent
HighwayFormation env (default: ``results/learned/bc_onramp``, behaviour
cloning of the formation expert with DAgger, deterministic actions).

The run is :func:`icv_envs.rl.bench.batched_sps` with the policy acting
(the second of two identical runs timed, ``--warmup`` batch steps before
the timed ``--steps``); the policy's inference is timed apart and left out
of the env's figures (it is the learner's cost, reported beside them). In
the same process, for the ratio: the same worlds with zero actions
(``batched_sps``' default kind) and with the expert's action for every
agent. Agent-steps count live agents only. Prints one line per kind and a
JSON line last (also to ``--out``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from icv_envs.rl.bench import batched_sps
from icv_envs.rl.models import load_model
from icv_envs.vector import BatchedWorlds


def shared_policy(model):
    """``policy(obs, mask)`` of :func:`batched_sps`: the model's actions for
    the live slots, zeros for the empty ones."""

    def policy(obs, mask):
        flat = mask.reshape(-1)
        acts = np.zeros((flat.shape[0], 2), dtype=np.float32)
        live = np.flatnonzero(flat)
        if len(live):
            acts[live] = model.act(obs.reshape((flat.shape[0],) + obs.shape[2:])[live])
        return acts.reshape(mask.shape + (2,))

    return policy


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--model", default=str(Path(__file__).resolve().parents[1] / "results/learned/bc_onramp"))
    p.add_argument("--worlds", type=int, default=16)
    p.add_argument("--vehicles", type=int, default=20)
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--warmup", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out")
    a = p.parse_args()
    model = load_model(a.model)
    bw = BatchedWorlds(1, config={"vehicles_count": int(a.vehicles), "initial_position": None}, seed=0)
    model.check_spaces("icv_envs/highway_formation-v0 (batched)", bw.envs[0].observation_space(bw.possible_agents[0]),
                       bw.envs[0].action_space(bw.possible_agents[0]))
    bw.close()
    res = {"model": str(a.model), "runs": []}
    common = dict(vehicles=a.vehicles, worlds=a.worlds, steps=a.steps, warmup=a.warmup, seed=a.seed)
    for kind, kw in (("trained", {"policy": shared_policy(model)}), ("zero", {}), ("expert", {"expert": True})):
        r = batched_sps(**common, **kw)
        res["runs"].append(r)
        extra = (f"; the policy's inference {r['policy_cpu_seconds'] / (a.worlds * a.steps) * 1e6:.0f} us per "
                 f"world-step more" if kind == "trained" else "")
        print(f"{kind:8s}: {r['agent_steps_per_cpu_s']:9.0f} agent-steps per CPU s of the env, "
              f"{r['live_agents_per_world']:.1f} live agents per world, {r['world_steps_per_cpu_s']:.0f} "
              f"world-steps per CPU s{extra}")
    line = json.dumps(res)
    if a.out:
        Path(a.out).write_text(line + "\n")
    print(line)


if __name__ == "__main__":
    main()
