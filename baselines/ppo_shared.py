"""One PPO policy (Stable-Baselines3, MlpPolicy) shared by every agent of an
icv_envs PettingZoo env (parameter sharing), through
:class:`icv_envs.rl.vec_env.ParallelVecEnv`.

Every ICV is an agent; agents join (on-ramp spawns) and leave (crash, exit,
end of road). The adapter gives each possible agent a VecEnv slot: absent
agents are masked (zero observation, reward 0, action ignored, done=True),
truncation bootstraps the value (``TimeLimit.truncated``), and finished
episodes are reset with seeds ``seed + copy + n_copies * episode``. Read the
adapter's module docstring for the details. ``--total-timesteps`` counts
slot-steps (agent-steps, placeholders of absent agents included).

    python baselines/ppo_shared.py --total-timesteps 500000 --seed 0 --out runs/ppo_shared
    python baselines/ppo_shared.py --env highway_formation_v0 --config '{"scenario": "on-ramp"}' --out runs/ppo_onramp
    icv-envs evaluate --env icv_envs/highway_formation-v0 --policy runs/ppo_shared --episodes 5
    python baselines/ppo_shared.py --env intersection_v0 --config '{"throughput": 1500, "duration": 60}' \
        --out runs/ppo_int

On the intersection (and highway-ramps) env every possible arrival of the
episode is a slot (143 for 60 s at 1500 veh/h): most slots are
placeholders at any time (``train.placeholder_fraction`` in run.json), so
use short ``duration`` configs; env steps with no vehicle on the road are
skipped inside the adapter (``train.empty_env_steps``).

Writes ``OUT/model.zip`` (``PPO.load``) and ``OUT/run.json`` (args, env id,
module and config, training stats, final evaluation with every agent driven
by the policy). Same seed, same result: the run is reproducible. Prints one
JSON line last. Needs ``pip install torch==2.13.0 && pip install stable-baselines3``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch
from stable_baselines3 import PPO

import icv_envs  # noqa: F401
from icv_envs.rl.envs import make_parallel_env, parse_config, resolve_env
from icv_envs.rl.evaluate import evaluate
from icv_envs.rl.models import platform_info, write_run_json
from icv_envs.rl.vec_env import ParallelVecEnv

ALGO = "ppo_shared"


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="ppo_shared.py", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", "--env-id", dest="env", default="icv_envs/highway_formation-v0",
                   help="PettingZoo id or module name (icv_envs/highway_formation-v0, highway_formation_v0)")
    p.add_argument("--config", default=None, help="env config: a JSON object or a .json file")
    p.add_argument("--total-timesteps", type=int, default=500_000, help="slot-steps (agents x env steps)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="runs/ppo_shared", help="output directory (model.zip, run.json)")
    p.add_argument("--n-copies", type=int, default=1, help="env copies; slots = copies x possible agents")
    p.add_argument("--n-steps", type=int, default=256, help="rollout length per slot")
    p.add_argument("--batch-size", type=int, default=256)
    p.add_argument("--n-epochs", type=int, default=10)
    p.add_argument("--learning-rate", type=float, default=3e-4)
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--gae-lambda", type=float, default=0.95)
    p.add_argument("--ent-coef", type=float, default=0.0)
    p.add_argument("--net-arch", default="64,64", help="hidden sizes of the policy and value MLPs")
    p.add_argument("--eval-episodes", type=int, default=3, help="final evaluation episodes (0: skip)")
    p.add_argument("--eval-seed", type=int, default=1000)
    p.add_argument("--verbose", type=int, default=0)
    args = p.parse_args(argv)
    for name in ("total_timesteps", "n_copies", "n_steps", "batch_size", "n_epochs"):
        if getattr(args, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    try:
        args.config_dict = parse_config(args.config)
        args.spec = resolve_env(args.env)
        args.hidden = [int(h) for h in args.net_arch.split(",") if h.strip()]
    except ValueError as exc:
        p.error(str(exc))
    if args.spec.kind != "pettingzoo":
        p.error(f"--env {args.env!r} is a Gymnasium env; use baselines/ppo_single.py for it")
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    torch.set_num_threads(1)
    out = Path(args.out)

    # 1. the env: PettingZoo parallel env(s) -> one VecEnv slot per possible agent
    venv = ParallelVecEnv(lambda: make_parallel_env(args.spec, args.config_dict), n_copies=args.n_copies,
                          seed=args.seed)

    # 2. the agent: one PPO actor-critic for all agents
    model = PPO(
        "MlpPolicy", venv,
        n_steps=args.n_steps, batch_size=args.batch_size, n_epochs=args.n_epochs,
        learning_rate=args.learning_rate, gamma=args.gamma, gae_lambda=args.gae_lambda, ent_coef=args.ent_coef,
        policy_kwargs={"net_arch": {"pi": args.hidden, "vf": args.hidden}},
        seed=args.seed, device="cpu", verbose=args.verbose,
    )

    # 3. train
    t0 = time.perf_counter()
    model.learn(total_timesteps=args.total_timesteps)
    wall = time.perf_counter() - t0
    eps = list(model.ep_info_buffer)
    train = {
        "timesteps": int(model.num_timesteps),
        "slots": venv.num_envs,
        "env_steps": int(model.num_timesteps // venv.num_envs) * venv.n_copies,
        "wall_seconds": wall,
        "slot_steps_per_second": model.num_timesteps / wall,
        "placeholder_fraction": venv.placeholder_fraction,  # share of slot-steps of absent agents
        "empty_env_steps": venv.empty_env_steps,  # open roads: env steps without any agent, skipped
        "agent_episodes_in_buffer": len(eps),
        "ep_rew_mean": float(np.mean([e["r"] for e in eps])) if eps else None,
        "ep_len_mean": float(np.mean([e["l"] for e in eps])) if eps else None,
    }
    venv.close()

    # 4. save the model and what evaluation needs to rebuild the env
    out.mkdir(parents=True, exist_ok=True)
    model.save(out / "model.zip")
    run = {
        "algo": ALGO,
        "env": args.spec.id,
        "env_kind": args.spec.kind,
        "env_module": args.spec.module,
        "config": args.config_dict,
        "possible_agents": venv.possible_agents,
        "observation_shape": list(venv.observation_space.shape),
        "action_shape": list(venv.action_space.shape),
        "args": {k: v for k, v in vars(args).items() if k not in ("spec", "config_dict")},
        "train": train,
        "platform": platform_info(),
    }
    write_run_json(out, run)

    # 5. final metrics: every agent driven by the learned policy, fresh seeds
    if args.eval_episodes > 0:
        res = evaluate(args.spec.id, str(out), episodes=args.eval_episodes, seed=args.eval_seed,
                       config=args.config_dict)
        run["eval"] = {k: v for k, v in res.items() if k != "per_episode"}
        write_run_json(out, run)
    print(json.dumps({"algo": ALGO, "out": str(out), "train": train, "eval": run.get("eval")}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
