"""PPO (Stable-Baselines3, MlpPolicy) on a single-agent icv_envs Gymnasium env.

One learned ego ICV among expert-driven ICVs (``icv_envs/HighwayFormation-v0``).
Readable top to bottom; every knob is a flag:

    python baselines/ppo_single.py --total-timesteps 200000 --seed 0 --out runs/ppo_single
    python baselines/ppo_single.py --config '{"scenario": "lane-drop"}' --out runs/ppo_single_ld
    icv-envs evaluate --env icv_envs/HighwayFormation-v0 --policy runs/ppo_single --episodes 5

Writes ``OUT/model.zip`` (``PPO.load``) and ``OUT/run.json`` (args, env id and
config, training stats, and the final evaluation through
:func:`icv_envs.rl.evaluate.evaluate` on ``--eval-episodes`` episodes with
seeds ``--eval-seed``, ``--eval-seed + 1``, ...). Prints one JSON line last.
Needs ``pip install torch==2.13.0 && pip install stable-baselines3``.
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
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv

import icv_envs  # noqa: F401  (registers the ids)
from icv_envs.rl.envs import make_gym_env, parse_config, resolve_env
from icv_envs.rl.evaluate import evaluate
from icv_envs.rl.models import platform_info, write_run_json

ALGO = "ppo_single"


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="ppo_single.py", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env-id", default="icv_envs/HighwayFormation-v0", help="an icv_envs Gymnasium id")
    p.add_argument("--config", default=None, help="env config: a JSON object or a .json file")
    p.add_argument("--total-timesteps", type=int, default=200_000, help="env steps (summed over --n-envs)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="runs/ppo_single", help="output directory (model.zip, run.json)")
    p.add_argument("--n-envs", type=int, default=1, help="env copies (DummyVecEnv)")
    p.add_argument("--n-steps", type=int, default=1024, help="rollout length per env copy")
    p.add_argument("--batch-size", type=int, default=64)
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
    for name in ("total_timesteps", "n_envs", "n_steps", "batch_size", "n_epochs"):
        if getattr(args, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    try:
        args.config_dict = parse_config(args.config)
        args.spec = resolve_env(args.env_id)
        args.hidden = [int(h) for h in args.net_arch.split(",") if h.strip()]
    except ValueError as exc:
        p.error(str(exc))
    if args.spec.kind != "gym":
        p.error(f"--env-id {args.env_id!r} is a PettingZoo env; use baselines/ppo_shared.py for it")
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    torch.set_num_threads(1)
    out = Path(args.out)

    # 1. the env: n copies of the Gymnasium env, each with SB3's Monitor (episode stats)
    def make_env():
        return Monitor(make_gym_env(args.spec, args.config_dict))

    venv = DummyVecEnv([make_env for _ in range(args.n_envs)])

    # 2. the agent: PPO with an MLP actor-critic on the flattened (V, 13) observation
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
        "wall_seconds": wall,
        "steps_per_second": model.num_timesteps / wall,
        "episodes_in_buffer": len(eps),
        "ep_rew_mean": float(np.mean([e["r"] for e in eps])) if eps else None,
        "ep_len_mean": float(np.mean([e["l"] for e in eps])) if eps else None,
    }
    venv.close()

    # 4. save the model and the metadata evaluation needs to rebuild the env
    out.mkdir(parents=True, exist_ok=True)
    model.save(out / "model.zip")
    run = {
        "algo": ALGO,
        "env": args.spec.id,
        "env_kind": args.spec.kind,
        "config": args.config_dict,
        "observation_shape": list(venv.observation_space.shape),
        "action_shape": list(venv.action_space.shape),
        "args": {k: v for k, v in vars(args).items() if k not in ("spec", "config_dict")},
        "train": train,
        "platform": platform_info(),
    }
    write_run_json(out, run)

    # 5. final metrics: the evaluation harness on fresh seeds
    if args.eval_episodes > 0:
        res = evaluate(args.spec.id, str(out), episodes=args.eval_episodes, seed=args.eval_seed,
                       config=args.config_dict)
        run["eval"] = {k: v for k, v in res.items() if k != "per_episode"}
        write_run_json(out, run)
    print(json.dumps({"algo": ALGO, "out": str(out), "train": train, "eval": run.get("eval")}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
