"""A training recipe for one PPO policy shared by every agent, aimed at the
expert: Stable-Baselines3 PPO through :class:`icv_envs.rl.vec_env.ParallelVecEnv`.

Why SB3: the task is one homogeneous policy (parameter sharing) over agents
with equal spaces and individual rewards, which is single-agent PPO on a
vector of agent slots; SB3's PPO is the reference implementation of that
(the same algorithm as CleanRL's ``ppo_continuous_action.py``, with tested
GAE / truncation bootstrapping), runs on one CPU thread, and its ``model.zip``
is what :mod:`icv_envs.rl.models` loads, so the evaluation harness and the
leaderboard run the result unchanged. A centralised critic (MAPPO) would need
TorchRL/BenchMARL; with individual rewards and the formation layer assigning
each agent its own target, an independent critic is the standard baseline.

Read top to bottom:

1. **Env** (``--env``, ``--config``, ``--action-type``, ``--layout``): the PettingZoo env,
   ``config["action"]["type"]`` set from ``--action-type`` when it is not the
   default ``ContinuousAction``; the script checks that the env really gives
   that action space (an env that does not implement the type is an error,
   never silently continuous). ``--layout``: one VecEnv slot per possible
   agent on highway-formation (every agent is there from the start); on the
   open roads, where vehicles keep arriving, the ``K`` reused slots of
   :mod:`icv_envs.rl.slots` with one episode per vehicle
   (:class:`icv_envs.rl.slots.VehicleEpisodes`): one slot per possible
   arrival would make 98-99% of the rollout placeholders. Vehicles that find
   every slot taken are driven by the expert during training (not in the
   learner's data); validation and the leaderboard drive every vehicle by
   the policy.
2. **Principled defaults**, not tuned on results:

   * ``gamma = 0.98``: at the 5 Hz policy rate the effective horizon
     ``1 / (1 - gamma)`` is 50 steps = 10 s, the time scale of the task (a
     lane change takes ~3-5 s, closing a 20 m formation gap at 2-5 m/s of
     relative speed 4-10 s, a 1 s headway at 25 m/s is 25 m); 0.99 at 5 Hz
     would look 20 s ahead, with noisier advantages.
   * ``gae_lambda = 0.95`` (the PPO paper's value).
   * **Reward scale**: per-step rewards are O(1) (progress ~0.33, formation
     ~0.5, safety in [-1, 0]); with gamma 0.98 returns are ~40, so the
     return is normalised by its running std (``VecNormalize(norm_obs=False,
     norm_reward=True)``), which keeps the value loss O(1) without changing
     the optimum. Training only: evaluation uses the env's reward.
   * **Observations** are not re-normalised: the env already scales every
     feature to [-1, 1] (highway-env's ``Kinematics`` with ``normalize``), so a
     running mean/std would only add state that the saved model would need.
   * **Exploration noise** ``--action-std 0.3,0.01`` (the Gaussian's initial
     std per action dimension, acceleration and steering): chosen so that one
     policy step (0.2 s) of noise changes the vehicle's velocity by about
     0.25 m/s along both axes. Acceleration: ``u_a * 3`` m/s^2 for 0.2 s is
     ``0.6 u_a`` m/s (``1.2 u_a`` braking), so std 0.3 gives 0.18-0.36 m/s.
     Steering: ``u_s * 30`` deg turns the kinematic bicycle at
     ``v / L tan(phi)`` = 25 / 2.8 * 0.52 ``u_s`` = 4.7 ``u_s`` rad/s at 25 m/s,
     i.e. a heading change of 0.94 ``u_s`` rad and a lateral velocity of
     23 ``u_s`` m/s after one step, so std 0.01 gives 0.23 m/s. SB3's default
     std of 1 (both axes) drives every vehicle off the road within a second.
     With ``FormationResidual`` (applied as ``expert + bound * r``) the stds
     are divided by the type's ``bound`` (default 0.25), capped at 1.
   * MLP 256-256 ReLU, the shape of ``baselines/bc_expert.py`` so that
     ``--init`` can load a clone; Adam 3e-4, 10 epochs, minibatch 512, clip 0.2.

3. **Initialisation** ``--init PATH`` (optional): start from a behaviour clone
   of the expert (a ``bc_expert.py`` model, same network), i.e. BC followed by
   RL fine-tuning (the BC-initialisation step of Rajeswaran et al. 2018,
   DAPG, without its BC term in the policy loss). A fresh critic would feed
   the pretrained actor random advantages, so for ``--critic-warmup`` slot-steps
   only the value function learns (actor frozen), then both.
4. **Train** ``--total-timesteps`` slot-steps (agent-steps, placeholders of
   absent agents included) or until ``--max-minutes`` of wall time. Every
   rollout appends a row to ``OUT/curve.csv``: slot-steps, env steps, wall
   seconds, mean return and crash share of the agent episodes that ended in
   it; every ``--eval-every`` slot-steps the policy also runs
   ``--eval-episodes`` whole episodes with every agent driven by it on the
   validation seeds ``--eval-seed`` + k (never used for training; the
   leaderboard uses other seeds again), adding the team return and
   collisions per 100 vehicles to the row.
5. **Save** ``OUT/model.zip`` = the checkpoint with the fewest validation
   collisions, ties by the highest validation return (``--select last``:
   the final weights). On the open roads (the env reports
   ``achieved_throughput``) the selection uses the target's own terms
   instead, because there the fewest collisions (and the highest team return:
   vehicles that stay collect per-step rewards) go to a policy that stops
   traffic: the highest validation throughput times the share of vehicles
   that did not collide (:func:`open_road_score`), then the fewest
   collisions, then the return (a first version, safety first and then
   throughput, kept the untrained policy of the first checkpoint, which
   stopped every vehicle: 0 collisions, 75 veh/h); ``OUT/final.zip``, ``OUT/run.json`` (args, config,
   training stats, wall time, the chosen checkpoint), ``OUT/curve.csv`` and
   ``OUT/curve.png``.

Training seeds: episode ``e`` of copy ``c`` resets with ``seed + c + n_copies * e``
(``--seed 0``: seeds 0, 1, 2, ...; a 15-minute run uses fewer than 5000).

    python baselines/ppo_recipe.py --config '{"scenario": "lane-drop"}' --max-minutes 14 --out runs/ppo_ld
    python baselines/ppo_recipe.py --config '{"scenario": "on-ramp"}' --init runs/bc_onramp --out runs/ppo_or
    python baselines/ppo_recipe.py --action-type DiscreteMetaAction --config '{"scenario": "lane-drop"}' --out runs/m

Needs ``pip install torch==2.13.0 && pip install stable-baselines3 matplotlib``.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecNormalize

import icv_envs  # noqa: F401
from icv_envs.rl.envs import make_parallel_env, parse_config, resolve_env
from icv_envs.rl.evaluate import evaluate
from icv_envs.rl.models import load_model, platform_info, write_run_json
from icv_envs.rl.slots import vehicle_slots_env
from icv_envs.rl.vec_env import ParallelVecEnv

ALGO = "ppo_recipe"
ACTION_TYPES = ("ContinuousAction", "DiscreteMetaAction", "FormationResidual")


def open_road_score(throughput: float, collisions_per_100: float) -> float:
    """Checkpoint score on the open roads: the validation throughput [veh/h]
    times the share of vehicles that did not collide. Both terms of the
    target (throughput near the expert's, at most 1 collision per 100
    vehicles) raise it; a policy that stops traffic scores its trickle, one
    that crashes half its vehicles half its throughput."""
    return float(throughput) * max(0.0, 1.0 - float(collisions_per_100) / 100.0)

CURVE_FIELDS = ("slot_steps", "env_steps", "wall_seconds", "agent_episodes", "agent_return", "agent_crash_share",
                "val_return", "val_collisions_per_100", "val_mean_speed", "val_throughput")


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="ppo_recipe.py", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", default="icv_envs/highway_formation-v0", help="PettingZoo id or module name")
    p.add_argument("--config", default=None, help="env config: a JSON object or a .json file")
    p.add_argument("--action-type", default="ContinuousAction", choices=ACTION_TYPES,
                   help="config['action']['type'] of the env (highway-env style)")
    p.add_argument("--init", default=None, help="a bc_expert.py model to start the actor from (BC -> PPO)")
    p.add_argument("--critic-warmup", type=int, default=None,
                   help="slot-steps with the actor frozen at the start (default: 2 rollouts with --init, else 0)")
    p.add_argument("--total-timesteps", type=int, default=5_000_000, help="slot-steps (agents x env steps)")
    p.add_argument("--max-minutes", type=float, default=14.0, help="stop training after this wall time")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="runs/ppo_recipe")
    p.add_argument("--layout", default="auto", choices=("auto", "agents", "slots"),
                   help="VecEnv slots: one per possible agent ('agents'), or the K reused vehicle slots of "
                        "icv_envs.rl.slots with per-vehicle episodes ('slots'); auto: slots on the open roads "
                        "(highway-ramps, intersection), agents on highway-formation")
    p.add_argument("--n-copies", type=int, default=1, help="env copies; slots = copies x possible agents")
    p.add_argument("--n-steps", type=int, default=256, help="rollout length per slot (env steps)")
    p.add_argument("--batch-size", type=int, default=512)
    p.add_argument("--n-epochs", type=int, default=10)
    p.add_argument("--learning-rate", type=float, default=3e-4)
    p.add_argument("--gamma", type=float, default=0.98)
    p.add_argument("--gae-lambda", type=float, default=0.95)
    p.add_argument("--clip-range", type=float, default=0.2)
    p.add_argument("--ent-coef", type=float, default=0.0)
    p.add_argument("--action-std", default="0.3,0.01",
                   help="initial std of the Gaussian per action dimension: acceleration,steering")
    p.add_argument("--net-arch", default="256,256")
    p.add_argument("--eval-every", type=int, default=100_000, help="slot-steps between validation evaluations")
    p.add_argument("--eval-episodes", type=int, default=2)
    p.add_argument("--eval-seed", type=int, default=90_000, help="validation seeds: eval_seed + k")
    p.add_argument("--select", default="best", choices=("best", "last"))
    args = p.parse_args(argv)
    for name in ("total_timesteps", "n_copies", "n_steps", "batch_size", "n_epochs", "eval_every", "eval_episodes"):
        if getattr(args, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    if args.max_minutes <= 0:
        p.error(f"--max-minutes must be > 0, got {args.max_minutes}")
    try:
        args.config_dict = parse_config(args.config)
        args.spec = resolve_env(args.env)
        args.hidden = [int(h) for h in args.net_arch.split(",") if h.strip()]
        args.std = [float(v) for v in args.action_std.split(",")]
    except ValueError as exc:
        p.error(str(exc))
    if len(args.std) != 2 or not all(0 < v <= 1 for v in args.std):
        p.error(f"--action-std {args.action_std!r} is invalid; allowed: two numbers in (0, 1], acceleration,steering")
    if args.spec.kind != "pettingzoo":
        p.error(f"--env {args.env!r} is a Gymnasium env; this recipe trains every agent of a PettingZoo env")
    if "action" in args.config_dict:
        p.error("give the action type with --action-type, not inside --config")
    if args.action_type != "ContinuousAction":
        args.config_dict["action"] = {"type": args.action_type}
    if args.layout == "auto":
        # the env family (its core module's name): every agent is there from the start only on highway_formation
        args.layout = "agents" if args.spec.family == "highway_formation" else "slots"
    if args.init is not None and args.action_type == "DiscreteMetaAction":
        p.error("--init loads a continuous behaviour clone; it does not apply to --action-type DiscreteMetaAction")
    return args


def check_action_type(env, action_type: str) -> None:
    """The env must give the action space the type stands for."""
    space = env.action_space(env.possible_agents[0])
    discrete = hasattr(space, "n")
    if (action_type == "DiscreteMetaAction") != discrete:
        raise SystemExit(f"--action-type {action_type}: the env gives action space {space}; this version of the env "
                         f"does not implement config['action']['type'] = {action_type!r}")


class Curve(BaseCallback):
    """Learning curve rows (CSV) and validation checkpoints."""

    def __init__(self, args, out: Path, venv: ParallelVecEnv, t0: float):
        super().__init__()
        self.args, self.out, self.venv, self.t0 = args, out, venv, t0
        self.rows: list[dict] = []
        self.ended: list[tuple[float, bool]] = []
        self.next_eval = 0
        self.best = None  # (collisions, -return, slot_steps)
        self.stop = False
        self.val_seconds = 0.0  # wall time spent in validation (inside the --max-minutes budget)

    def _on_step(self) -> bool:
        for info in self.locals["infos"]:
            ep = info.get("episode")
            if ep is not None and info.get("active", False):
                self.ended.append((ep["r"], bool(info.get("crashed", False))))
        if time.perf_counter() - self.t0 > 60.0 * self.args.max_minutes:
            self.stop = True
            return False
        return True

    def _on_rollout_end(self) -> None:
        n = self.model.num_timesteps
        row = {"slot_steps": n, "env_steps": self.venv_env_steps(), "wall_seconds": time.perf_counter() - self.t0,
               "agent_episodes": len(self.ended),
               "agent_return": float(np.mean([r for r, _ in self.ended])) if self.ended else None,
               "agent_crash_share": float(np.mean([c for _, c in self.ended])) if self.ended else None}
        self.ended = []
        if n >= self.next_eval:
            row.update(self.validate())
            self.next_eval = n + self.args.eval_every
        self.rows.append(row)
        write_curve(self.out / "curve.csv", self.rows)
        print(json.dumps({k: (round(v, 3) if isinstance(v, float) else v) for k, v in row.items()}), flush=True)

    def venv_env_steps(self) -> int:
        return int(self.venv.slot_steps // self.venv.num_envs) * self.venv.n_copies + self.venv.empty_env_steps

    def validate(self) -> dict:
        ckpt = self.out / "checkpoints" / f"{self.model.num_timesteps}"
        ckpt.mkdir(parents=True, exist_ok=True)
        self.model.save(ckpt / "model.zip")
        t = time.perf_counter()
        res = evaluate(self.args.spec.id, str(ckpt), episodes=self.args.eval_episodes, seed=self.args.eval_seed,
                       config=self.args.config_dict)
        self.val_seconds += time.perf_counter() - t
        vehicles = res.get("spawned") or res.get("vehicles") or 1
        coll = 100.0 * res["collisions"] / vehicles
        thr = res.get("achieved_throughput")
        if thr is None:  # closed road: fewest collisions, then the highest return
            key = (coll, -res["episode_return"], self.model.num_timesteps)
        else:  # open road: throughput discounted by the collision rate (see the docstring, 5.)
            key = (-open_road_score(float(thr), coll), coll, -res["episode_return"], self.model.num_timesteps)
        if self.best is None or key < self.best:
            self.best = key
        row = {"val_return": res["episode_return"], "val_collisions_per_100": coll, "val_mean_speed": res["mean_speed"]}
        if thr is not None:
            row["val_throughput"] = float(thr)
        return row


def write_curve(path: Path, rows: list[dict]) -> None:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CURVE_FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k) for k in CURVE_FIELDS})


def plot_curve(path: Path, rows: list[dict], title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    val = [r for r in rows if r.get("val_return") is not None]
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
    x = [r["env_steps"] for r in val]
    ax[0].plot(x, [r["val_return"] for r in val], "o-")
    ax[0].set(xlabel="env steps", ylabel="validation team return", title=title)
    ax[1].plot(x, [r["val_collisions_per_100"] for r in val], "o-", color="C3")
    ax[1].set(xlabel="env steps", ylabel="collisions per 100 vehicles")
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    args = parse_args(argv)
    torch.set_num_threads(1)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    # 1. env: one VecEnv slot per possible agent (or per reused vehicle slot on the open roads);
    #    reward normalised for training only
    if args.layout == "slots":
        def make():
            return vehicle_slots_env(args.spec.id, args.config_dict)
    else:
        def make():
            return make_parallel_env(args.spec, args.config_dict)
    venv = ParallelVecEnv(make, n_copies=args.n_copies, seed=args.seed)
    check_action_type(venv.envs[0], args.action_type)
    env = VecNormalize(venv, norm_obs=False, norm_reward=True, gamma=args.gamma)

    # 2. the shared actor-critic
    policy_kwargs = {"net_arch": {"pi": args.hidden, "vf": args.hidden}, "activation_fn": torch.nn.ReLU}
    model = PPO("MlpPolicy", env, n_steps=args.n_steps, batch_size=args.batch_size, n_epochs=args.n_epochs,
                learning_rate=args.learning_rate, gamma=args.gamma, gae_lambda=args.gae_lambda,
                clip_range=args.clip_range, ent_coef=args.ent_coef, policy_kwargs=policy_kwargs,
                seed=args.seed, device="cpu", verbose=0)

    # 3. optional behaviour-clone initialisation of the actor (the critic stays fresh)
    actor_names = []
    if args.init is not None:
        clone = load_model(args.init)
        clone.check_spaces(args.spec.id, venv.observation_space, venv.action_space)
        src = clone.model.policy.state_dict()
        dst = model.policy.state_dict()
        actor_names = [k for k in dst if k.startswith(("mlp_extractor.policy_net", "action_net"))]
        for k in actor_names:
            if src[k].shape != dst[k].shape:
                raise SystemExit(f"--init {args.init}: {k} has shape {tuple(src[k].shape)}, expected "
                                 f"{tuple(dst[k].shape)} (--net-arch must match the clone's)")
            dst[k] = src[k].clone()
        model.policy.load_state_dict(dst)
        actor_names.append("log_std")
    if args.action_type != "DiscreteMetaAction":  # the exploration noise (see the docstring)
        bound = np.ones(2)
        if args.action_type == "FormationResidual":
            b = args.config_dict["action"].get("bound", 0.25)
            bound = np.broadcast_to(np.asarray(b, dtype=float), (2,))
        std = np.minimum(np.asarray(args.std) / bound, 1.0)
        with torch.no_grad():
            model.policy.log_std.copy_(torch.as_tensor(np.log(std), dtype=torch.float32))
    warmup = args.critic_warmup if args.critic_warmup is not None else (
        2 * args.n_steps * venv.num_envs if args.init else 0)

    # 4. train (critic warm-up with the actor frozen, then everything)
    t0 = time.perf_counter()
    curve = Curve(args, out, venv, t0)
    params = dict(model.policy.named_parameters())
    if warmup > 0:
        for k in actor_names:
            params[k].requires_grad_(False)
        model.learn(total_timesteps=min(warmup, args.total_timesteps), callback=curve)
        for k in actor_names:
            params[k].requires_grad_(True)
    if not curve.stop and model.num_timesteps < args.total_timesteps:
        model.learn(total_timesteps=args.total_timesteps - model.num_timesteps, callback=curve,
                    reset_num_timesteps=False)
    model.save(out / "final.zip")
    rows = curve.rows
    if not rows or rows[-1]["slot_steps"] != model.num_timesteps or rows[-1].get("val_return") is None:
        rows.append({"slot_steps": model.num_timesteps, "env_steps": curve.venv_env_steps(),
                     "wall_seconds": time.perf_counter() - t0, **curve.validate()})
        write_curve(out / "curve.csv", rows)
    wall = time.perf_counter() - t0  # training + validation

    # 5. the saved model: the best validation checkpoint (or the final weights)
    chosen = "final" if args.select == "last" else str(curve.best[-1])
    src = out / "final.zip" if chosen == "final" else out / "checkpoints" / chosen / "model.zip"
    (out / "model.zip").write_bytes(src.read_bytes())
    train = {"timesteps": int(model.num_timesteps), "slots": venv.num_envs, "env_steps": curve.venv_env_steps(),
             "wall_seconds": wall, "validation_seconds": curve.val_seconds,
             "placeholder_fraction": venv.placeholder_fraction, "critic_warmup": warmup,
             "stopped_by_time": curve.stop, "chosen_checkpoint": chosen, "chosen_validation": curve.best}
    venv.close()
    run = {"algo": ALGO, "env": args.spec.id, "env_kind": args.spec.kind, "env_module": args.spec.module,
           "config": args.config_dict, "action_type": args.action_type, "init": args.init,
           "possible_agents": venv.possible_agents, "observation_shape": list(venv.observation_space.shape),
           "action_shape": list(venv.action_space.shape or ()),
           "args": {k: v for k, v in vars(args).items() if k not in ("spec", "config_dict")},
           "train": train, "platform": platform_info()}
    write_run_json(out, run)
    plot_curve(out / "curve.png", rows, f"{ALGO} {args.config_dict.get('scenario', args.spec.id)}")
    print(json.dumps({"algo": ALGO, "out": str(out), "train": train, "last": rows[-1]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
