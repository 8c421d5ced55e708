"""Re-export of :mod:`icv_envs.sim.metrics`, where the run metrics are
defined (below the environments, which use them). Kept so that existing
imports ``from icv_envs.experiments.metrics import run_metrics`` work."""

from icv_envs.sim.metrics import *  # noqa: F401,F403
from icv_envs.sim.metrics import __all__  # noqa: F401
