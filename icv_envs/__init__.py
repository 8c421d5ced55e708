"""icv_envs: Gymnasium and PettingZoo environments for intelligent and
connected vehicles (ICVs), with the cooperative-driving framework of Xu et al.
(IET ITS 2021) as scripted experts.

Importing the package registers the Gymnasium ids (``icv_envs/...-v0``) and the
PettingZoo ids (``icv_envs/..._v0`` style, see :data:`PETTINGZOO_IDS`).
"""

from __future__ import annotations

import gymnasium as gym

from icv_envs import _kernel_cache

__version__ = "0.1.0"

# numba's cache of the kernels rebuilt where a kernel module it depends on
# changed since it was written (icv_envs/_kernel_cache.py)
_kernel_cache.refresh()

GYM_IDS = {
    "icv_envs/HighwayFormation-v0": "icv_envs.envs.highway_formation:HighwayFormationEnv",
    "icv_envs/HighwayRamps-v0": "icv_envs.envs.highway_ramps:HighwayRampsEnv",
    "icv_envs/Intersection-v0": "icv_envs.envs.intersection:IntersectionEnv",
}
PETTINGZOO_IDS = {
    "icv_envs/highway_formation-v0": "icv_envs.envs.highway_formation_v0",
    "icv_envs/highway_ramps-v0": "icv_envs.envs.highway_ramps_v0",
    "icv_envs/intersection-v0": "icv_envs.envs.intersection_v0",
}


def _register() -> None:
    for env_id, entry in GYM_IDS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=entry)
    try:
        import pettingzoo
    except ImportError:  # pragma: no cover
        return
    if not hasattr(pettingzoo, "register"):  # PettingZoo < 1.27 has no registry
        return
    for env_id, module in PETTINGZOO_IDS.items():
        if env_id not in pettingzoo.parallel_registry:
            pettingzoo.register("parallel", env_id, entry_point=f"{module}:parallel_env")
        if env_id not in pettingzoo.aec_registry:
            pettingzoo.register("aec", env_id, entry_point=f"{module}:env")


_register()

import sys as _sys  # noqa: E402

from icv_envs.envs import highway_formation_v0, highway_ramps_v0, intersection_v0  # noqa: E402

# ``import icv_envs.highway_formation_v0`` works as a submodule import, as
# ``import pettingzoo.butterfly.pistonball_v6`` does: the same module objects
for _m in (highway_formation_v0, highway_ramps_v0, intersection_v0):
    _sys.modules[f"{__name__}.{_m.__name__.rsplit('.', 1)[1]}"] = _m
del _m

__all__ = ["highway_formation_v0", "highway_ramps_v0", "intersection_v0", "GYM_IDS", "PETTINGZOO_IDS", "__version__"]
