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

Timed: the batch's ``step`` calls only, in process CPU time (the policy's
inference is timed apart and reported beside it: it is the learner's cost,
not the env's). As ``icv_envs.rl.bench.batched_sps``: the same run (same
seed, same steps) is made twice and the second is timed; ``--warmup``
batch steps before the timed ``--steps``. In the same run, for the ratio:
the same worlds with zero actions (``batched_sps``' default kind) and with
the expert's action for every agent. Agent-steps count live agents only.
Prints one line per kind and a JSON line last (also to ``--out``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from icv_envs.rl.models import load_model
from icv_envs.vector import BatchedWorlds


def run(kind: str, model, worlds: int, vehicles: int, steps: int, warmup: int, seed: int) -> dict:
    """One kind of actions (``trained``, ``zero``, ``expert``), the second
    of two identical runs timed."""
    cfg = {"vehicles_count": int(vehicles), "initial_position": None}
    for timed in (False, True):
        bw = BatchedWorlds(worlds, config=cfg, seed=seed, expert=kind == "expert")
        obs, mask = bw.reset()
        acts = np.zeros((worlds, bw.K, 2), dtype=np.float32)
        env_cpu = infer_cpu = 0.0
        agent_steps = 0
        for i in range(warmup + steps):
            c0 = time.process_time()
            if kind == "trained":
                live = np.flatnonzero(mask.reshape(-1))
                acts = np.zeros((worlds * bw.K, 2), dtype=np.float32)
                if len(live):
                    acts[live] = model.act(obs.reshape((worlds * bw.K,) + obs.shape[2:])[live])
                acts = acts.reshape(worlds, bw.K, 2)
            elif kind == "expert":
                acts = bw.expert_actions
            c1 = time.process_time()
            obs, rew, term, trunc, mask2, info = bw.step(acts)
            c2 = time.process_time()
            if i >= warmup:
                agent_steps += int(mask.sum())
                infer_cpu += c1 - c0
                env_cpu += c2 - c1
            mask = mask2
        bw.close()
    return {"actions": kind, "worlds": int(worlds), "vehicles_per_world": int(vehicles), "steps": int(steps),
            "agent_steps": agent_steps, "env_cpu_seconds": env_cpu, "inference_cpu_seconds": infer_cpu,
            "agent_steps_per_cpu_s": agent_steps / env_cpu, "world_steps_per_cpu_s": worlds * steps / env_cpu,
            "live_agents_per_world": agent_steps / (worlds * steps)}


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
    for kind in ("trained", "zero", "expert"):
        r = run(kind, model, a.worlds, a.vehicles, a.steps, a.warmup, a.seed)
        res["runs"].append(r)
        extra = (f"; the policy's inference {r['inference_cpu_seconds'] / (a.worlds * a.steps) * 1e6:.0f} us per "
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
