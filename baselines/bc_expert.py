"""Behaviour cloning of the env's expert (with optional DAgger), one policy
shared by every agent of an icv_envs PettingZoo env: the formation expert on
the highway-formation env (the default), the configured ``method``'s
controller on the highway-ramps and intersection envs (``--env intersection_v0``;
``--config '{"method": "fcfs"}'`` clones FCFS instead of ``multi-vp``).

1. Collect ``--expert-steps`` env steps with the expert driving every agent,
   recording each live agent's observation and ``infos[agent]["expert_action"]``.
2. Fit an MLP to those actions by mean squared error (Adam, minibatches).
3. DAgger (``--dagger-iters`` > 0): roll out the *learner* for
   ``--dagger-steps`` env steps per iteration, label every visited
   observation with the expert action the env puts in ``infos``, add them to
   the data set, refit. This fixes the covariate shift of plain BC (the
   learner's small errors lead to states the expert never visits).
4. Each learner rollout scores the fit that drove it (failures, i.e.
   collisions + vehicles that left the road, per 1000 agent-steps, ties by
   reward); one more rollout scores the last fit, and
   the best fit is saved (``--no-select-best``: the last). Clones vary a lot
   from fit to fit; this keeps a bad last fit from being the result.

The network is the actor of a Stable-Baselines3 PPO ``MlpPolicy`` (the mean
of its Gaussian is the cloned action; ``log_std`` is set to ``--log-std``), so
``OUT/model.zip`` loads with ``PPO.load`` like the PPO baselines, is
evaluated by :func:`icv_envs.rl.evaluate.evaluate`, and can seed PPO
fine-tuning. ``OUT/run.json`` records args, env id and config, data set size,
losses and the final evaluation (every agent driven by the clone).

    python baselines/bc_expert.py --out runs/bc_expert                 # all five scenarios
    python baselines/bc_expert.py --config '{"scenario": "on-ramp"}' --out runs/bc_onramp
    icv-envs evaluate --env icv_envs/highway_formation-v0 --policy runs/bc_expert --config '{"scenario": "lane-drop"}'
    python baselines/bc_expert.py --env intersection_v0 --config '{"throughput": 1500, "duration": 60}' \
        --expert-steps 3000 --dagger-iters 2 --dagger-steps 1500 --out runs/bc_intersection
    icv-envs evaluate --env intersection_v0 --policy runs/bc_intersection --episodes 5

``--dataset DIR`` (optionally ``DIR::DATASET_ID``) takes the expert data of
step 1 from a Minari dataset written by ``icv-envs dataset`` (every step's
observation and expert action, over all its episodes) instead of
collecting ``--expert-steps`` steps; DAgger (step 3) then labels the
learner's own rollouts on ``--config`` as usual (``--dagger-iters 0``: pure
offline BC from the dataset). The dataset's spaces must be the env's. E.g.

    icv-envs dataset --env icv_envs/highway_formation-v0 --config '{"scenario": "on-ramp"}' --episodes 50 \
        --out runs/datasets
    python baselines/bc_expert.py --config '{"scenario": "on-ramp"}' --dataset runs/datasets --out runs/bc_ds

On the highway-formation env, ``--scenarios`` collects episodes from each
listed scenario in turn (on top of ``--config``), for one clone that covers
them all; by default all five (free, lane-drop, lane-change, off-ramp,
on-ramp), or only the scenario ``--config`` names. The other envs have no
scenarios: episodes come from ``--config`` alone. On the open roads (ramps,
intersection) an episode runs until its time is up; env steps without any
vehicle on the road are not counted in ``--expert-steps`` /
``--dagger-steps``. Prints one JSON line
last. Needs ``pip install torch==2.13.0 && pip install stable-baselines3``.
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
from icv_envs.envs.scenarios import SCENARIOS
from icv_envs.rl.envs import make_parallel_env, parse_config, resolve_env, step_until_agents
from icv_envs.rl.evaluate import evaluate
from icv_envs.rl.models import platform_info, write_run_json
from icv_envs.rl.vec_env import ParallelVecEnv

ALGO = "bc_expert"
ALL_SCENARIOS = ("free", "lane-drop", "lane-change", "off-ramp", "on-ramp")


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="bc_expert.py", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", "--env-id", dest="env", default="icv_envs/highway_formation-v0",
                   help="PettingZoo id or module name (icv_envs/highway_formation-v0, highway_formation_v0)")
    p.add_argument("--config", default=None, help="env config: a JSON object or a .json file")
    p.add_argument("--scenarios", default=None, help="highway-formation env: comma-separated scenarios to collect "
                   "from in turn, on top of --config, or 'config' for --config alone (default: all five, or only the "
                   f"--config scenario if it names one); allowed: {', '.join(sorted(SCENARIOS))}. Other envs: 'config' "
                   "(the default)")
    p.add_argument("--expert-steps", type=int, default=6000, help="env steps with the expert driving")
    p.add_argument("--dataset", default=None, help="Minari dataset DIR (MINARI_DATASETS_PATH) or DIR::DATASET_ID "
                   "(default id icv_envs/<family>/expert-v0): the expert data instead of --expert-steps")
    p.add_argument("--dagger-iters", type=int, default=6, help="DAgger iterations (0: plain BC)")
    p.add_argument("--dagger-steps", type=int, default=3000, help="env steps of learner rollouts per iteration")
    p.add_argument("--epochs", type=int, default=10, help="passes over the data set per fit")
    p.add_argument("--batch-size", type=int, default=256)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--net-arch", default="256,256", help="hidden sizes of the MLP")
    p.add_argument("--log-std", type=float, default=-2.0, help="log std of the saved Gaussian policy")
    p.add_argument("--no-select-best", dest="select_best", action="store_false",
                   help="save the last fit instead of the fit with the fewest failures (collisions + left road) "
                        "in its learner rollout")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="runs/bc_expert", help="output directory (model.zip, run.json)")
    p.add_argument("--eval-episodes", type=int, default=3, help="final evaluation episodes (0: skip)")
    p.add_argument("--eval-seed", type=int, default=1000)
    args = p.parse_args(argv)
    for name in ("expert_steps", "epochs", "batch_size"):
        if getattr(args, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    for name in ("dagger_iters", "dagger_steps", "eval_episodes"):
        if getattr(args, name) < 0:
            p.error(f"--{name.replace('_', '-')} must be >= 0, got {getattr(args, name)}")
    try:
        args.config_dict = parse_config(args.config)
        args.spec = resolve_env(args.env)
        args.hidden = [int(h) for h in args.net_arch.split(",") if h.strip()]
    except ValueError as exc:
        p.error(str(exc))
    if args.spec.kind != "pettingzoo":
        p.error(f"--env {args.env!r} is a Gymnasium env; behaviour cloning runs on the PettingZoo env")
    has_scenarios = args.spec.family == "highway_formation"
    if args.scenarios is None:
        args.scenarios = "config" if "scenario" in args.config_dict or not has_scenarios else ",".join(ALL_SCENARIOS)
    args.scenario_list = [s.strip() for s in args.scenarios.split(",") if s.strip() and s.strip() != "config"]
    if args.scenario_list and not has_scenarios:
        p.error(f"--scenarios {args.scenarios!r}: env {args.spec.id!r} has no scenarios; allowed there: 'config' "
                f"(collect from --config alone)")
    bad = [s for s in args.scenario_list if s not in SCENARIOS]
    if bad:
        p.error(f"unknown scenarios {bad}; allowed: {', '.join(sorted(SCENARIOS))}")
    return args


def collect(envs, n_steps: int, seed: int, policy=None, left_road_fails: bool = True
            ) -> tuple[np.ndarray, np.ndarray, dict]:
    """Roll out ``n_steps`` env steps (episodes cycle through ``envs``, reset
    with seeds ``seed``, ``seed + 1``, ...). ``policy=None``: the expert
    drives; otherwise ``policy(obs_batch) -> actions`` drives every agent.
    Returns observations, the expert's actions for them, and rollout stats.
    ``left_road_fails``: leaving the road counts as a failure (the
    intersection: driving back out of the approach road); on the highway it
    is the end of the road, a truncation, as on the leaderboard."""
    X, Y = [], []
    steps, episodes, ret, collisions, left_road = 0, 0, 0.0, 0, 0
    while steps < n_steps:
        env = envs[episodes % len(envs)]
        obs, infos = env.reset(seed=seed + episodes)
        while steps < n_steps:
            if not env.agents:  # open road: step through the time without vehicles, or stop at the episode's end
                skipped = step_until_agents(env)
                if skipped:
                    obs, infos = skipped[-1][0], skipped[-1][4]
                if not env.agents:
                    break
            agents = list(env.agents)
            o = np.stack([obs[a] for a in agents])
            expert = np.stack([infos[a]["expert_action"] for a in agents]).astype(np.float32)
            X.append(o)
            Y.append(expert)
            acts = expert if policy is None else policy(o)
            obs, rew, term, trunc, infos = env.step({a: acts[i] for i, a in enumerate(agents)})
            ret += float(sum(rew.values()))
            steps += 1
        m = env.metrics()
        collisions += int(m["collisions"])
        left_road += int(m.get("left_road", 0))
        episodes += 1
    samples = int(sum(len(x) for x in X))
    stats = {"env_steps": steps, "episodes": episodes, "samples": samples,
             "return_per_episode": ret / episodes, "reward_per_agent_step": ret / max(samples, 1),
             "collisions": int(collisions), "collisions_per_1000_agent_steps": 1000.0 * collisions / max(samples, 1),
             "left_road": int(left_road),
             "failures_per_1000_agent_steps": 1000.0 * (collisions + left_road_fails * left_road) / max(samples, 1)}
    return np.concatenate(X), np.clip(np.concatenate(Y), -1.0, 1.0), stats


def load_dataset(arg: str, family: str, obs_space, act_space) -> tuple[np.ndarray, np.ndarray, dict]:
    """Observations and expert actions of every step of a Minari dataset
    (``DIR`` or ``DIR::ID``, as written by ``icv-envs dataset``)."""
    import os

    import minari

    from icv_envs.rl.dataset import DEFAULT_DATASET_ID

    root, _, did = arg.partition("::")
    did = did or DEFAULT_DATASET_ID.format(family=family)
    if not Path(root).is_dir():
        raise SystemExit(f"--dataset {arg!r}: directory {root!r} does not exist")
    os.environ["MINARI_DATASETS_PATH"] = str(Path(root).resolve())
    if did not in minari.list_local_datasets():
        raise SystemExit(f"--dataset {arg!r}: no dataset {did!r} there; found: {sorted(minari.list_local_datasets())}")
    ds = minari.load_dataset(did)
    if ds.observation_space.shape != obs_space.shape or ds.action_space != act_space:
        raise SystemExit(f"--dataset {did!r} has observation shape {ds.observation_space.shape} and action space "
                         f"{ds.action_space}; the env has {obs_space.shape} and {act_space}")
    X, Y = [], []
    for ep in ds.iterate_episodes():
        X.append(np.asarray(ep.observations[:-1], dtype=np.float32))
        Y.append(np.asarray(ep.actions, dtype=np.float32))
    X, Y = np.concatenate(X), np.clip(np.concatenate(Y), -1.0, 1.0)
    return X, Y, {"dataset_id": did, "episodes": int(ds.total_episodes), "samples": int(len(X))}


def fit(policy, X: np.ndarray, Y: np.ndarray, epochs: int, batch_size: int, lr: float, rng) -> dict:
    """Fit the mean of the policy's Gaussian to ``Y`` by MSE; returns losses
    (train, and on a 10 % hold-out)."""
    n = len(X)
    perm = rng.permutation(n)
    n_val = max(1, n // 10) if n >= 20 else 0
    val, tr = perm[:n_val], perm[n_val:]
    Xt, Yt = torch.as_tensor(X), torch.as_tensor(Y)
    params = [p for name, p in policy.named_parameters()
              if not name.startswith(("value_net", "mlp_extractor.value_net")) and name != "log_std"]
    opt = torch.optim.Adam(params, lr=lr)

    def mean_action(x):
        return policy.get_distribution(x).distribution.mean

    policy.set_training_mode(True)
    train_loss = float("nan")
    for _ in range(epochs):
        order = tr[rng.permutation(len(tr))]
        total, count = 0.0, 0
        for k in range(0, len(order), batch_size):
            b = torch.as_tensor(order[k:k + batch_size])
            loss = torch.nn.functional.mse_loss(mean_action(Xt[b]), Yt[b])
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * len(b)
            count += len(b)
        train_loss = total / max(count, 1)
    policy.set_training_mode(False)
    with torch.no_grad():
        val_loss = float(torch.nn.functional.mse_loss(mean_action(Xt[val]), Yt[val])) if n_val else None
    return {"train_mse": train_loss, "val_mse": val_loss, "samples": n}


def main(argv=None) -> int:
    args = parse_args(argv)
    torch.set_num_threads(1)
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    out = Path(args.out)
    t0 = time.perf_counter()

    # 1. envs to collect from: --config, or --config on top of each scenario
    cfgs = [dict(args.config_dict, scenario=s) for s in args.scenario_list] or [dict(args.config_dict)]
    envs = [make_parallel_env(args.spec, dict(c, expert_in_info=True)) for c in cfgs]

    # 2. the network: the actor of an SB3 PPO MlpPolicy (so model.zip loads like the PPO baselines)
    shell = ParallelVecEnv(lambda: make_parallel_env(args.spec, args.config_dict), seed=args.seed)
    model = PPO("MlpPolicy", shell, n_steps=8, batch_size=8, seed=args.seed, device="cpu",
                policy_kwargs={"net_arch": {"pi": args.hidden, "vf": args.hidden}, "activation_fn": torch.nn.ReLU})
    policy = model.policy
    with torch.no_grad():
        policy.log_std.fill_(args.log_std)

    def learner(obs_batch):
        with torch.no_grad():
            return np.clip(policy.get_distribution(torch.as_tensor(obs_batch)).distribution.mean.numpy(), -1, 1)

    # 3. behaviour cloning on expert rollouts
    if args.dataset is not None:  # the expert data from a Minari dataset
        X, Y, stats = load_dataset(args.dataset, args.spec.family, shell.observation_space, shell.action_space)
    else:
        X, Y, stats = collect(envs, args.expert_steps, seed=args.seed * 100_000,
                              left_road_fails=args.spec.family == "intersection")
    history = [{"round": 0, "driver": "dataset" if args.dataset else "expert", "rollout": stats,
                "fit": fit(policy, X, Y, args.epochs, args.batch_size, args.lr, rng)}]

    # 4. DAgger: learner drives, the expert labels, aggregate, refit. Each
    #    learner rollout also scores the fit that drove it (collisions, + left
    #    road at the intersection, per 1000 agent-steps, then reward per agent-step); a last rollout scores
    #    the last fit, and the best-scoring fit is saved (--no-select-best: the last).
    snapshots = [{k: v.clone() for k, v in policy.state_dict().items()}]
    scores = []
    n_iters = args.dagger_iters if args.dagger_steps > 0 else 0
    for it in range(1, n_iters + 2 if args.select_best and n_iters else n_iters + 1):
        Xn, Yn, stats = collect(envs, args.dagger_steps, seed=args.seed * 100_000 + 10_000 * it, policy=learner,
                                 left_road_fails=args.spec.family == "intersection")
        scores.append((stats["failures_per_1000_agent_steps"], -stats["reward_per_agent_step"]))
        if it > n_iters:  # the scoring rollout of the last fit
            history[-1]["score_rollout"] = stats
            break
        X, Y = np.concatenate([X, Xn]), np.concatenate([Y, Yn])
        history.append({"round": it, "driver": "learner", "rollout": stats,
                        "fit": fit(policy, X, Y, args.epochs, args.batch_size, args.lr, rng)})
        snapshots.append({k: v.clone() for k, v in policy.state_dict().items()})
    chosen = len(history) - 1
    if args.select_best and len(scores) == len(snapshots):
        chosen = min(range(len(scores)), key=lambda k: scores[k])
        policy.load_state_dict(snapshots[chosen])
    for env in envs:
        env.close()
    wall = time.perf_counter() - t0

    # 5. save model.zip (SB3 PPO format) and run.json
    out.mkdir(parents=True, exist_ok=True)
    model.save(out / "model.zip")
    shell.close()
    train = {"samples": int(len(X)), "wall_seconds": wall, "saved_round": chosen, "final": history[chosen]["fit"],
             "rounds": history}
    run = {
        "algo": ALGO,
        "env": args.spec.id,
        "env_kind": args.spec.kind,
        "env_module": args.spec.module,
        "config": args.config_dict,
        "scenarios": args.scenario_list,
        "observation_shape": list(shell.observation_space.shape),
        "action_shape": list(shell.action_space.shape),
        "args": {k: v for k, v in vars(args).items() if k not in ("spec", "config_dict")},
        "train": train,
        "platform": platform_info(),
    }
    write_run_json(out, run)

    # 6. final metrics: every agent driven by the clone, fresh seeds; on --config
    #    (what evaluate() uses by default) and on each collection scenario
    if args.eval_episodes > 0:
        def final_eval(cfg):
            res = evaluate(args.spec.id, str(out), episodes=args.eval_episodes, seed=args.eval_seed, config=cfg)
            return {k: v for k, v in res.items() if k != "per_episode"}

        run["eval"] = final_eval(args.config_dict)
        if args.scenario_list:
            run["eval_by_scenario"] = {s: final_eval(c) for s, c in zip(args.scenario_list, cfgs)}
        write_run_json(out, run)
    by_scenario = {k: v["collisions"] for k, v in run.get("eval_by_scenario", {}).items()}
    print(json.dumps({"algo": ALGO, "out": str(out), "samples": int(len(X)), "saved_round": chosen,
                      "final_fit": history[chosen]["fit"],
                      "eval": run.get("eval"), "collisions_by_scenario": by_scenario}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
