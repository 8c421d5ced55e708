"""Expert datasets in Minari format (offline RL, imitation).

:func:`record_expert_dataset` runs the env's expert and writes a Minari
dataset (``minari.create_dataset_from_buffers``, Arrow storage) under
``out`` (Minari's ``MINARI_DATASETS_PATH``), id ``icv_envs/<family>/expert-v0``
unless given:

* a **Gymnasium id** (one ego among expert-driven vehicles): one Minari
  episode per env episode (seeds ``seed, seed + 1, ...``), the ego driven by
  the expert;
* a **PettingZoo id** (every vehicle an agent, all expert-driven): one Minari
  episode per vehicle, from its first observation to the step it
  terminates or is truncated (env episodes use seeds ``seed, seed + 1, ...``);
  vehicles of one env episode come in the order they appear.

Each step stores the observation (``T + 1`` per episode, the last one the
final observation), the expert's action in the configured action type's
space (``ContinuousAction``: the expert's ``[u_a, u_s]``;
``FormationResidual``: zeros, the residual that reproduces the expert;
``DiscreteMetaAction`` has no expert form and raises ``ValueError``), the
reward, the termination and truncation flags, and infos (``T + 1`` rows):
``env_seed``, ``env_episode``, ``vehicle`` (vehicle id), ``time`` (s),
``speed`` (m/s), ``crashed`` and one ``reward_<term>`` column per reward
component (0 at the first observation), each of shape ``(T + 1, 1)`` (Minari
0.5's Arrow storage cannot decode per-step scalars). ``env_seed`` makes every episode
replayable: reset the env with it and drive every vehicle with the recorded
expert (the tests check one episode bit for bit).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from icv_envs._args import check_int
from icv_envs.rl.envs import _check_config, env_family, make_gym_env, make_parallel_env, resolve_env

__all__ = ["record_expert_dataset", "DEFAULT_DATASET_ID"]

DEFAULT_DATASET_ID = "icv_envs/{family}/expert-v0"


def _expert_in_space(core, ex):
    a = core._act_type.expert_action(ex)
    if a is None:
        raise ValueError(f"the expert has no form in action type {core._act_type.name!r}; record the dataset with "
                         f"ContinuousAction or FormationResidual (config['action']['type'])")
    return np.asarray(a)


class _Track:
    """One episode being recorded."""

    def __init__(self, obs, info: dict, seed: int, ep: int, vehicle: int, t: float, reward_keys) -> None:
        self.obs = [np.asarray(obs)]
        self.act, self.rew, self.term, self.trunc = [], [], [], []
        self.keys = reward_keys
        self.info = {k: [] for k in ("env_seed", "env_episode", "vehicle", "time", "speed", "crashed")}
        self.info.update({f"reward_{k}": [] for k in reward_keys})
        self.seed, self.ep, self.vehicle = seed, ep, vehicle
        self._add_info(info, t)

    def _add_info(self, info: dict, t: float) -> None:
        i = self.info
        i["env_seed"].append(self.seed)
        i["env_episode"].append(self.ep)
        i["vehicle"].append(self.vehicle)
        i["time"].append(float(t))
        i["speed"].append(float(info.get("speed", np.nan)))
        i["crashed"].append(bool(info.get("crashed", False)))
        parts = info.get("rewards", {})
        for k in self.keys:
            i[f"reward_{k}"].append(float(parts.get(k, 0.0)))

    def add(self, action, obs, reward, term, trunc, info, t) -> None:
        self.act.append(np.asarray(action))
        self.obs.append(np.asarray(obs))
        self.rew.append(float(reward))
        self.term.append(bool(term))
        self.trunc.append(bool(trunc))
        self._add_info(info, t)

    def buffer(self, eid: int):
        from minari.data_collector import EpisodeBuffer

        # (T + 1, 1) columns: Minari 0.5's Arrow storage fails to decode per-step scalars
        infos = {k: np.asarray(v).reshape(-1, 1) for k, v in self.info.items()}
        return EpisodeBuffer(id=eid, seed=self.seed, observations=np.stack(self.obs), actions=np.stack(self.act),
                             rewards=list(self.rew), terminations=list(self.term), truncations=list(self.trunc),
                             infos=infos)


_INFO_NEEDED = ("speed", "crashed", "rewards")  # what _Track reads from an info


def record_expert_dataset(env, episodes: int, out, seed: int = 0, config: dict | None = None,
                          dataset_id: str | None = None, progress: bool = False) -> dict:
    """Record ``episodes`` env episodes of the expert as a Minari dataset under
    ``out``; returns a summary (dataset id, path, episodes, steps, seconds)."""
    import minari
    from minari.dataset.minari_dataset import DATASET_ID_RE

    check_int("episodes", episodes, 1)
    check_int("seed", seed, 0)
    spec = resolve_env(env)
    if dataset_id is not None:
        # minari parses ids as (namespace/)name-vN and needs the version (it fails after writing otherwise)
        m = DATASET_ID_RE.fullmatch(dataset_id) if isinstance(dataset_id, str) else None
        if m is None or m.group("version") is None:
            raise ValueError(f"dataset_id = {dataset_id!r}; allowed: None (the default "
                             f"{DEFAULT_DATASET_ID.format(family=env_family(spec))!r}) or a Minari id "
                             f"(namespace/)name-vN, e.g. 'icv_envs/my_data/expert-v0'")
    cfg = _check_config(config)
    # the recording reads the expert's label and these info keys every step
    if cfg.get("expert_in_info", True) is not True:
        raise ValueError(f"config['expert_in_info'] = {cfg['expert_in_info']!r}; the dataset records the expert's "
                         f"actions from the infos: allowed: True (or leave it out)")
    ik = cfg.get("info_keys")
    if isinstance(ik, (list, tuple)) and not set(_INFO_NEEDED) <= set(ik):
        raise ValueError(f"config['info_keys'] = {list(ik)!r}; the dataset records {list(_INFO_NEEDED)} from the "
                         f"infos: allowed: None (all keys) or a list holding them")
    family = env_family(spec)
    dataset_id = dataset_id or DEFAULT_DATASET_ID.format(family=family)
    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    os.environ["MINARI_DATASETS_PATH"] = str(out)
    t0 = time.perf_counter()
    buffers = []
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=int(episodes), desc="expert episodes")
    if spec.kind == "gym":
        genv = make_gym_env(spec, cfg)
        core = genv.unwrapped
        keys = list(core.config["reward"])
        obs_space, act_space = genv.observation_space, genv.action_space
        env_spec = genv.spec
        for ep in range(int(episodes)):
            obs, info = genv.reset(seed=seed + ep)
            tr = _Track(obs, info, seed + ep, ep, int(core._ego_vid), core.world.time, keys)
            done = False
            while not done:
                a = _expert_in_space(core, info["expert_action"]).astype(act_space.dtype)
                obs, r, term, trunc, info = genv.step(a)
                tr.add(a, obs, r, term, trunc, info, core.world.time)
                done = term or trunc
            buffers.append(tr.buffer(len(buffers)))
            if bar:
                bar.update(1)
        genv.close()
    else:
        cfg.setdefault("expert_in_info", True)
        par = make_parallel_env(spec, cfg)
        core = par.core
        keys = list(core.config["reward"])
        a0 = par.possible_agents[0]
        obs_space, act_space = par.observation_space(a0), par.action_space(a0)
        env_spec = None  # a PettingZoo env has no Gymnasium spec
        from icv_envs.rl.envs import episode_finished

        for ep in range(int(episodes)):
            obs, infos = par.reset(seed=seed + ep)
            open_ = {a: _Track(obs[a], infos[a], seed + ep, ep, int(a[4:]), core.world.time, keys) for a in obs}
            done_tracks = []
            while not episode_finished(par):
                acts = {a: _expert_in_space(core, infos[a]["expert_action"]).astype(act_space.dtype)
                        for a in par.agents}
                obs, rew, term, trunc, infos = par.step(acts)
                t = core.world.time
                for a in obs:
                    if a in open_:
                        open_[a].add(acts[a], obs[a], rew[a], term[a], trunc[a], infos[a], t)
                        if term[a] or trunc[a]:
                            done_tracks.append(open_.pop(a))
                    elif not (term[a] or trunc[a]):  # appeared in this step
                        open_[a] = _Track(obs[a], infos[a], seed + ep, ep, int(a[4:]), t, keys)
            # vehicles still open when the episode is over (none normally: all are truncated)
            done_tracks += [tr for tr in open_.values() if tr.act]
            for tr in sorted(done_tracks, key=lambda tr: tr.vehicle):
                buffers.append(tr.buffer(len(buffers)))
            if bar:
                bar.update(1)
        par.close()
    if bar:
        bar.close()
    if dataset_id in minari.list_local_datasets():
        minari.delete_dataset(dataset_id)
    ds = minari.create_dataset_from_buffers(
        dataset_id, buffers, env=env_spec, observation_space=obs_space, action_space=act_space,
        algorithm_name=f"{family} expert", author="icv_envs",
        description=f"Expert of {spec.id} (config {cfg!r}); {'one episode per vehicle' if spec.kind != 'gym' else 'the ego'}"
                    f", env seeds {seed}..{seed + int(episodes) - 1}",
        data_format="arrow",
    )
    return {"dataset_id": dataset_id, "path": str(out), "env": spec.id, "config": cfg,
            "env_episodes": int(episodes), "episodes": int(ds.total_episodes), "steps": int(ds.total_steps),
            "seed": seed, "seconds": time.perf_counter() - t0}
