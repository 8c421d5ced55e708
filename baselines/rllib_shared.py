"""Ray RLlib PPO with ONE policy shared by every agent of an icv_envs
PettingZoo env (parameter sharing), on RLlib's new API stack.

Every ICV is an agent; agents join (on-ramp spawns) and leave (crash, exit,
end of road) mid-episode, which RLlib's multi-agent episodes handle. The env
goes through RLlib's ``ParallelPettingZooEnv`` wrapper, subclassed in
:mod:`icv_envs.rl.rllib_compat` to fix what does not fit (ordered
``possible_agents`` with a space for each, ``render()`` without a mode, the
episode end). Every agent id maps to the module ``"shared"``; the ``(8, 13)``
observation is flattened by RLlib's ``FlattenObservations`` connector.

    python baselines/rllib_shared.py --iterations 50 --seed 0 --out runs/rllib_shared
    python baselines/rllib_shared.py --config '{"scenario": "on-ramp"}' --iterations 20 --out runs/rllib_onramp
    python baselines/rllib_shared.py --evaluate runs/rllib_shared --episodes 5    # evaluate a saved run

One local env runner, no remote workers, one CPU (``ray.init(num_cpus=1)``).
``--train-batch-size`` counts env steps (every live agent acts in each);
``--minibatch-size`` and the PPO updates count agent steps. Episodes are
sampled whole (``batch_mode="complete_episodes"``): with episodes cut at the
batch boundary, RLlib 2.60 sends no action for an agent that joins on the
very step another agent finishes, if that step ends the batch.

Writes ``OUT/checkpoint/`` (``Algorithm.save_to_path``; the shared policy is
the RLModule in ``OUT/checkpoint/learner_group/learner/rl_module/shared``) and
``OUT/run.json`` (args, env id, module and config, per-iteration training
stats, and the final evaluation: every agent driven by the policy's mean
action, metrics as in :func:`icv_envs.rl.evaluate.evaluate`). Prints one JSON
line last. Needs ``pip install "ray[rllib]"`` (``pip install -e ".[rllib]"``;
RLlib pins its own gymnasium version).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import icv_envs  # noqa: F401  (registers the ids)
from icv_envs.rl.envs import parse_config, resolve_env
from icv_envs.rl.models import platform_info, write_run_json

ALGO = "rllib_shared"
MODULE_ID = "shared"


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="rllib_shared.py", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", "--env-id", dest="env", default="icv_envs/highway_formation-v0",
                   help="PettingZoo id or module name (icv_envs/highway_formation-v0, highway_formation_v0)")
    p.add_argument("--config", default=None, help="env config: a JSON object or a .json file")
    p.add_argument("--iterations", type=int, default=50, help="training iterations (algo.train() calls)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="runs/rllib_shared", help="output directory (checkpoint/, run.json)")
    p.add_argument("--train-batch-size", type=int, default=4000, help="env steps sampled per iteration")
    p.add_argument("--batch-mode", default="complete_episodes", choices=["complete_episodes", "truncate_episodes"],
                   help="complete_episodes (default) samples whole episodes, at least --train-batch-size env steps; "
                        "truncate_episodes cuts episodes at the batch boundary, which RLlib 2.60 mishandles when an "
                        "agent joins on the step another one finishes (the joiner gets no action)")
    p.add_argument("--minibatch-size", type=int, default=128, help="agent steps per SGD minibatch")
    p.add_argument("--num-epochs", type=int, default=10, help="passes over each train batch")
    p.add_argument("--lr", type=float, default=3e-4)
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--lambda", dest="lambda_", type=float, default=0.95, help="GAE lambda")
    p.add_argument("--entropy-coeff", type=float, default=0.0)
    p.add_argument("--net-arch", default="64,64", help="hidden sizes of the policy and value MLPs")
    p.add_argument("--eval-episodes", type=int, default=3, help="final evaluation episodes (0: skip)")
    p.add_argument("--eval-seed", type=int, default=1000)
    p.add_argument("--evaluate", metavar="RUN", default=None,
                   help="do not train: evaluate the run directory (or checkpoint) RUN for --episodes episodes "
                        "(env config: --config, else the run's)")
    p.add_argument("--episodes", type=int, default=5, help="episodes for --evaluate")
    args = p.parse_args(argv)
    for name in ("iterations", "train_batch_size", "minibatch_size", "num_epochs", "episodes"):
        if getattr(args, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    if args.eval_episodes < 0:
        p.error(f"--eval-episodes must be >= 0, got {args.eval_episodes}")
    try:
        args.config_dict = parse_config(args.config)
        args.spec = resolve_env(args.env)
        args.hidden = [int(h) for h in args.net_arch.split(",") if h.strip()]
    except ValueError as exc:
        p.error(str(exc))
    if args.spec.kind != "pettingzoo":
        p.error(f"--env {args.env!r} is a Gymnasium env; this script trains on the PettingZoo env")
    return args


def evaluate_run(run_or_checkpoint, episodes: int, seed: int, config: dict | None = None) -> dict:
    """Harness-style metrics of a saved run, every agent driven by the policy."""
    from icv_envs.rl.rllib_compat import evaluate_checkpoint

    return evaluate_checkpoint(run_or_checkpoint, episodes=episodes, seed=seed, config=config)


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.evaluate:
        import torch

        torch.set_num_threads(1)
        try:
            res = evaluate_run(args.evaluate, args.episodes, args.eval_seed,
                               args.config_dict if args.config else None)
        except ValueError as exc:
            print(f"rllib_shared.py: error: {exc}", file=sys.stderr)
            return 2
        print(json.dumps(res))
        return 0

    import gymnasium
    import ray
    import torch
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.connectors.env_to_module import FlattenObservations
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig
    from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec
    from ray.tune.registry import register_env

    from icv_envs.rl.rllib_compat import ENV_NAME, make_rllib_env

    torch.set_num_threads(1)
    out = Path(args.out).resolve()

    # 1. Ray on one CPU, and the env: PettingZoo parallel env -> RLlib MultiAgentEnv
    started_ray = not ray.is_initialized()
    if started_ray:
        ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    register_env(ENV_NAME, make_rllib_env)
    env_config = {"env": args.spec.id, "config": args.config_dict}
    probe = make_rllib_env(env_config)  # for the record: agents and spaces
    a0 = probe.possible_agents[0]
    obs_shape = list(probe.get_observation_space(a0).shape)
    act_shape = list(probe.get_action_space(a0).shape)
    possible_agents = list(probe.possible_agents)
    probe.close()

    # 2. PPO: one local env runner, one RLModule ("shared") that every agent maps to
    config = (
        PPOConfig()
        .environment(ENV_NAME, env_config=env_config)
        .framework("torch")
        .env_runners(
            num_env_runners=0, num_envs_per_env_runner=1, batch_mode=args.batch_mode,
            env_to_module_connector=lambda env, spaces=None, device=None: FlattenObservations(multi_agent=True),
        )
        .learners(num_learners=0)
        .training(
            train_batch_size_per_learner=args.train_batch_size, minibatch_size=args.minibatch_size,
            num_epochs=args.num_epochs, lr=args.lr, gamma=args.gamma, lambda_=args.lambda_,
            entropy_coeff=args.entropy_coeff,
        )
        .multi_agent(policies={MODULE_ID}, policy_mapping_fn=lambda agent_id, *a, **kw: MODULE_ID)
        .rl_module(
            rl_module_spec=MultiRLModuleSpec(rl_module_specs={MODULE_ID: RLModuleSpec()}),
            model_config=DefaultModelConfig(fcnet_hiddens=args.hidden, fcnet_activation="tanh"),
        )
        .debugging(seed=args.seed)
    )
    algo = config.build_algo()

    # 3. train
    history = []
    t0 = time.perf_counter()
    for it in range(1, args.iterations + 1):
        r = algo.train()
        er = r.get("env_runners", {})
        lr_stats = r.get("learners", {}).get(MODULE_ID, {})
        row = {
            "iteration": it,
            "env_steps": int(r.get("num_env_steps_sampled_lifetime", 0)),
            "episode_return_mean": er.get("episode_return_mean"),
            "episode_len_mean": er.get("episode_len_mean"),
            "episodes": er.get("num_episodes"),
            "policy_loss": lr_stats.get("policy_loss"),
            "vf_loss": lr_stats.get("vf_loss"),
            "entropy": lr_stats.get("entropy"),
            "seconds": r.get("time_this_iter_s"),
        }
        history.append({k: (float(v) if hasattr(v, "__float__") and not isinstance(v, int) else v)
                        for k, v in row.items()})
        print(json.dumps(history[-1]), flush=True)
    wall = time.perf_counter() - t0

    # 4. save the checkpoint and what evaluation needs to rebuild the env
    ckpt = Path(algo.save_to_path(str(out / "checkpoint")))
    algo.stop()
    if started_ray:
        ray.shutdown()
    train = {"iterations": args.iterations, "env_steps": history[-1]["env_steps"], "wall_seconds": wall,
             "env_steps_per_second": history[-1]["env_steps"] / wall, "last": history[-1], "history": history}
    run = {
        "algo": ALGO,
        "env": args.spec.id,
        "env_kind": args.spec.kind,
        "env_module": args.spec.module,
        "config": args.config_dict,
        "possible_agents": possible_agents,
        "observation_shape": obs_shape,
        "action_shape": act_shape,
        "checkpoint": str(ckpt),
        "module": str(ckpt / "learner_group" / "learner" / "rl_module" / MODULE_ID),
        "args": {k: v for k, v in vars(args).items() if k not in ("spec", "config_dict")},
        "train": train,
        "platform": {**platform_info(), "ray": ray.__version__, "gymnasium": gymnasium.__version__},
    }
    write_run_json(out, run)

    # 5. final metrics: every agent driven by the policy's mean action, fresh seeds
    if args.eval_episodes > 0:
        res = evaluate_run(out, args.eval_episodes, args.eval_seed, args.config_dict)
        run["eval"] = {k: v for k, v in res.items() if k != "per_episode"}
        write_run_json(out, run)
    print(json.dumps({"algo": ALGO, "out": str(out), "checkpoint": str(ckpt),
                      "train": {k: v for k, v in train.items() if k != "history"}, "eval": run.get("eval")}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
