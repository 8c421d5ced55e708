"""Policies that act through the agents' action space.

``make_policy(name, seed)`` returns a callable ``policy(env, observations,
infos) -> {agent: action}`` for a PettingZoo parallel env of this package:

* ``expert``: the formation expert (:class:`FormationExpert`), the paper's
  controller (Bezier lane changes, preview steering, feedback law, IDM
  safety envelope), in the env's action type (``FormationResidual``: the
  zero residual); an error for ``DiscreteMetaAction``, which has no form
  of the expert's continuous action;
* ``zero``: coast straight (action ``[0, 0]``; ``DiscreteMetaAction``:
  IDLE), a do-nothing baseline;
* ``random``: uniform random actions over the action space (seeded).
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
            to_action = env.core._act_type.expert_action  # (until stop 45 the raw [u_a, u_s], whatever the type)
            if to_action(np.zeros(2)) is None:
                raise ValueError(f"policy 'expert' drives with the expert's continuous [u_a, u_s], which action type "
                                 f"{env.core._act_type.name!r} cannot take; allowed with it: zero, random")
            acts = env.expert_actions()
            return {a: to_action(acts[a]) for a in env.agents}

        return expert
    if name == "zero":

        def zero(env, observations, infos):
            at = env.core._act_type  # ([0, 0]; DiscreteMetaAction's IDLE)
            return {a: at.idle_action() for a in env.agents}

        return zero
    rng = np.random.default_rng(seed)

    def random(env, observations, infos):
        agents = env.agents
        if not agents:
            return {}
        space = env.action_space(agents[0])
        if hasattr(space, "n"):  # (Discrete)
            return {a: int(space.start + rng.integers(space.n)) for a in agents}
        return {a: rng.uniform(-1, 1, 2).astype(np.float32) for a in agents}

    return random
