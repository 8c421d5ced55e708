"""Paired runs of two trees on one intersection setting through the array
path (stop 47): each repetition runs the reference tree, then the tree
under test (fresh processes, PYTHONPATH=<tree>), the expert driving every
agent through step_rows, ``--warmup`` s untimed then ``--seconds`` timed;
prints agent-steps per CPU s, the ratio and a hash of the final state and
metrics (which must be the same for both trees).

    python results/bench/stop47/int_pairs.py REF TEST [--method multi-vp] [--throughput 2200]
        [--seed 0] [--warmup 100] [--seconds 300] [--reps 2] [--api rows|dicts]
"""
import argparse, hashlib, json, os, statistics, subprocess, sys

CHILD = r"""
import hashlib, json, sys, time
import numpy as np
from icv_envs.envs.intersection_v0 import parallel_env
method, tp, seed, warm, secs, api = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5]), sys.argv[6]
kw = {"expert_in_info": False} if api == "rows" else {}
env = parallel_env(method=method, throughput=tp, duration=warm + secs + 10, **kw)
obs, infos = env.reset(seed=seed)
core = env.core
def step():
    global infos
    if api == "rows":
        env.step_rows(core.expert_actions())
    else:
        infos = env.step({a: infos[a]["expert_action"] for a in env.agents})[4]
while core.world.time < warm - 1e-9:
    step()
t0 = core.world.time; n = 0; c0 = time.process_time()
while core.world.time < t0 + secs - 1e-9:
    n += env.num_agents; step()
cpu = time.process_time() - c0
f = core.world.fleet
h = hashlib.sha256(f.vid.tobytes() + f.x.tobytes() + f.y.tobytes() + f.speed.tobytes() + json.dumps(env.metrics(), sort_keys=True, default=str).encode()).hexdigest()[:16]
print(json.dumps({"rate": n / cpu, "agent_steps": n, "hash": h}))
"""

def run(tree, a):
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-c", CHILD, a.method, str(a.throughput), str(a.seed), str(a.warmup),
                          str(a.seconds), a.api], env=env, cwd="/tmp", check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])

p = argparse.ArgumentParser()
p.add_argument("reference"); p.add_argument("test")
p.add_argument("--method", default="multi-vp"); p.add_argument("--throughput", type=float, default=2200.0)
p.add_argument("--seed", type=int, default=0); p.add_argument("--warmup", type=float, default=100.0)
p.add_argument("--seconds", type=float, default=300.0); p.add_argument("--reps", type=int, default=2)
p.add_argument("--api", default="rows", choices=("rows", "dicts"))
a = p.parse_args()
ratios = []
for i in range(a.reps):
    r, t = run(a.reference, a), run(a.test, a)
    same = r["hash"] == t["hash"] and r["agent_steps"] == t["agent_steps"]
    ratios.append(t["rate"] / r["rate"])
    print(f"{a.method} {a.throughput:g} veh/h seed {a.seed} ({a.api}): reference {r['rate']:,.0f}, test {t['rate']:,.0f} "
          f"agent-steps per CPU s, ratio {ratios[-1]:.2f}; same state and metrics: {same} ({t['hash']})", flush=True)
print(f"median ratio {statistics.median(ratios):.2f}")
