"""Intersection step cost of two source trees, alternately, in one run (issue 10).

    git worktree add /tmp/ref <commit>
    python scripts/bench_trees.py /tmp/ref . [--reps 6] [--steps 1200] [--throughput 2200]

Each repetition runs the reference tree, then the tree under test, each in a
fresh process (``PYTHONPATH=<tree>``): multi-vp, the zones filled to 60
vehicles, then ``--steps`` policy steps timed (process CPU time; every
vehicle an agent, the expert's action from the infos, as ``icv-envs bench
intersection``). Prints each pair's ratio (agent-steps per CPU second, test /
reference) and their median; a shared machine moves single figures by 20%
or more, the pairs' median much less. Both trees must drive the same
vehicles (the agent-step counts are checked).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

CHILD = """
import json, sys, time
from icv_envs.envs.intersection_v0 import parallel_env
steps, tp = int(sys.argv[1]), float(sys.argv[2])
env = parallel_env(method="multi-vp", throughput=tp, duration=300.0 + steps / 5.0 + 10.0)
obs, infos = env.reset(seed=0)
while len(env.agents) < 60 and env.core.world.time < 300:
    obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
c0, n = time.process_time(), 0
for _ in range(steps):
    n += len(env.agents)
    obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
print(json.dumps({"cpu": time.process_time() - c0, "agent_steps": n}))
"""


def _run(tree: Path, steps: int, tp: float) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-c", CHILD, str(steps), str(tp)], cwd=tree, env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("reference")
    p.add_argument("test")
    p.add_argument("--reps", type=int, default=6)
    p.add_argument("--steps", type=int, default=1200)
    p.add_argument("--throughput", type=float, default=2200.0)
    a = p.parse_args(argv)
    ref, test = Path(a.reference).resolve(), Path(a.test).resolve()
    ratios, rows = [], []
    for i in range(a.reps):
        r, t = _run(ref, a.steps, a.throughput), _run(test, a.steps, a.throughput)
        if r["agent_steps"] != t["agent_steps"]:
            raise SystemExit(f"the trees drive different vehicles ({r['agent_steps']} vs {t['agent_steps']} "
                             f"agent-steps): not a like-for-like comparison")
        sr, st = r["agent_steps"] / r["cpu"], t["agent_steps"] / t["cpu"]
        ratios.append(st / sr)
        rows.append({"reference": sr, "test": st, "ratio": st / sr})
        print(f"rep {i + 1}: reference {sr:,.0f}, test {st:,.0f} agent-steps per CPU s, ratio {st / sr:.2f}",
              flush=True)
    res = {"median_ratio": statistics.median(ratios), "pairs": rows, "steps": a.steps,
           "agent_steps": r["agent_steps"], "throughput": a.throughput}
    print(f"median ratio test / reference over {a.reps} pairs: {res['median_ratio']:.2f}")
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
