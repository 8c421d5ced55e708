"""The intersection step on settings the bench is not measured on (stops 40-41):
agent-steps per CPU second of 1200 policy steps after the zones hold 60
vehicles (or 300 s), the expert's action from the infos, as
``scripts/bench_trees.py --case intersection`` does but with the method,
demand and seed given. Run from outside the checkout, alternately per tree:

    PYTHONPATH=<tree> python intersection_settings.py METHOD THROUGHPUT SEED
"""
import json
import sys
import time

from icv_envs.envs.intersection_v0 import parallel_env

method, tp, seed = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
steps = 1200
env = parallel_env(method=method, throughput=tp, duration=300.0 + steps / 5.0 + 10.0)
obs, infos = env.reset(seed=seed)
while len(env.agents) < 60 and env.core.world.time < 300:
    obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
c0, n = time.process_time(), 0
for _ in range(steps):
    n += len(env.agents)
    obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
cpu = time.process_time() - c0
m = env.core.metrics()
print(json.dumps({"method": method, "throughput": tp, "seed": seed, "agent_steps": n,
                  "agent_steps_per_cpu_s": n / cpu, "collisions": m["collisions"], "cleared": m.get("cleared")}))
