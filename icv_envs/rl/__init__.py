"""Learned policies against the formation expert.

* :class:`icv_envs.rl.vec_env.ParallelVecEnv`: a PettingZoo parallel env whose
  agents join and leave, as a Stable-Baselines3 ``VecEnv`` for one shared
  policy (one slot per possible agent, absent agents masked).
* :class:`icv_envs.rl.slots.SlotParallelEnv`: any env as a fixed set of ``K``
  agent slots (reused as vehicles come and go, empty ones masked) for
  SuperSuit's vector envs, RLlib's stock ``ParallelPettingZooEnv`` and
  TorchRL's ``PettingZooWrapper``.
* :func:`icv_envs.rl.dataset.record_expert_dataset`: the expert as a Minari
  dataset (``icv-envs dataset``).
* :mod:`icv_envs.rl.envs`: resolve env ids / module names, build envs.
* :mod:`icv_envs.rl.models`: the model format of the ``baselines/`` scripts
  (SB3 ``model.zip`` + ``run.json``) and its loader.
* :func:`icv_envs.rl.evaluate.evaluate`: run ``expert``, a reference method
  (``idm``, ``lane-lp`` on the highway-ramps env; ``single-vp``, ``fcfs`` on
  the intersection), ``zero``, ``random`` or a saved model on the same
  scenarios and report the env's metrics (one table for learned and
  scripted policies).
* :func:`icv_envs.rl.bench.bench_train`: env steps per second, alone and
  inside SB3 PPO training, against highway-env's ``highway-fast-v0``.

Stable-Baselines3 and torch are optional (``pip install torch==2.13.0 &&
pip install stable-baselines3``): they are imported only by the adapter, by
the training scripts and when a saved model is evaluated.
"""

from __future__ import annotations

__all__ = ["ParallelVecEnv", "evaluate", "bench_train"]


def __getattr__(name):  # lazy: keep torch / SB3 out of ``import icv_envs.rl``
    if name == "ParallelVecEnv":
        from icv_envs.rl.vec_env import ParallelVecEnv

        return ParallelVecEnv
    if name == "evaluate":
        from icv_envs.rl.evaluate import evaluate

        return evaluate
    if name == "bench_train":
        from icv_envs.rl.bench import bench_train

        return bench_train
    raise AttributeError(f"module 'icv_envs.rl' has no attribute {name!r}")
