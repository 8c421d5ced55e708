"""Stop 43's intersection bench (``icv-envs bench intersection``: 3 seeds,
500 s timed after 100 s of warm-up, agent-steps per CPU s) run on another
tree's code: the bench function is loaded from THIS tree's
``icv_envs/experiments/intersection_bench.py`` (it imports only the env),
the env from ``PYTHONPATH=<tree>``. Run from outside the checkout:
``PYTHONPATH=<tree> python bench_intersection_pairs.py`` -> one JSON line
(the totals and per-seed rates)."""
import importlib.util
import json
from pathlib import Path

here = Path(__file__).resolve().parents[3] / "icv_envs" / "experiments" / "intersection_bench.py"
spec = importlib.util.spec_from_file_location("_bench_intersection_stop43", here)
mod = importlib.util.module_from_spec(spec)
spec.loader.exec_module(mod)
import icv_envs  # noqa: E402  (the tree under test)

res = mod.bench_intersection(echo=lambda s: None)
print(json.dumps({"tree": str(Path(icv_envs.__file__).resolve().parents[1]),
                  "agent_steps_per_cpu_s": res["agent_steps_per_cpu_s"],
                  "per_seed": [p["agent_steps_per_cpu_s"] for p in res["per_seed"]],
                  "agent_steps": res["agent_steps"], "collisions": res["collisions"], "lost": res["lost"],
                  "mean_agents": res["mean_agents"]}))
