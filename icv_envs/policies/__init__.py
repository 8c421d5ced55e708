"""Policies that act through the agents' action space.

``make_policy(name, seed)`` returns a callable ``policy(env, observations,
infos) -> {agent: action}`` for a PettingZoo parallel env of this package:

* ``expert``: the formation expert (:class:`FormationExpert`), the paper's
  controller (Bezier lane changes, preview steering, feedback law, IDM
  safety envelope);
* ``zero``: coast straight (action ``[0, 0]``), a do-nothing baseline;
* ``random``: uniform random actions (seeded).
"""

from __future__ import annotations

import numpy as np

from icv_envs.policies.formation_expert import ExpertParams, FormationExpert

__all__ = ["ExpertParams", "FormationExpert", "POLICIES", "make_policy"]

POLICIES = ("expert", "zero", "random")


def make_policy(name: str, seed: int | None = None):
    if name not in POLICIES:
        raise ValueError(f"unknown policy {name!r}; allowed: {list(POLICIES)}")
    if name == "expert":

        def expert(env, observations, infos):
            acts = env.expert_actions()
            return {a: acts[a] for a in env.agents}

        return expert
    if name == "zero":

        def zero(env, observations, infos):
            return {a: np.zeros(2, dtype=np.float32) for a in env.agents}

        return zero
    rng = np.random.default_rng(seed)

    def random(env, observations, infos):
        return {a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents}

    return random
