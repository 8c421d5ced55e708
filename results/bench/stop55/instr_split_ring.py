"""Stop 55: where a step of the paper's ring goes by instructions, by the object that runs them (the split of
``results/bench/stop53/instr_split.py``: callgrind, only the counted steps instrumented), through PettingZoo's
dicts (the ring bench's default loop), the lean dicts and the array API. The question: with the Python of the
core gone and the dict layer at its floor, could the ring reach 4x SUMO? (The kernels' share bounds it.)

    python results/bench/stop55/instr_split_ring.py TREE [--api dicts|lean|rows] [--warm 2500] [--steps 50]
    python results/bench/stop55/instr_split_ring.py TREE --env intersection --api dicts --warm 1000 --steps 200
"""
import argparse, json, os, shutil, subprocess, sys, tempfile
from collections import Counter
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "stop53"))
from instr_split import split, group  # noqa: E402

CHILD = """
import os, sys, time
api, steps, warm, d, which, seed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], sys.argv[5], int(sys.argv[6])
from icv_envs.experiments.bench import APIS
from icv_envs.experiments.sumo_bench import _icv_steps, _vehicle_steps
def wait(name):
    while not os.path.exists(os.path.join(d, name)):
        time.sleep(0.01)
if which == "ring":
    from icv_envs.envs.highway_ramps_v0 import parallel_env
    env = parallel_env(vgr=1.0 / 3.0, duration=600.0, method="formation", **APIS[api])
    env.reset(seed=seed)
    run = lambda k: _icv_steps(env, k, api)
    count = lambda: _vehicle_steps(env)
else:  # the intersection bench's loop (multi-vp, 2200 veh/h, --seed), ``warm`` policy steps first
    from icv_envs.envs.intersection_v0 import parallel_env
    from icv_envs.experiments.intersection_bench import _stepper
    env = parallel_env(method="multi-vp", throughput=2200.0, duration=(warm + steps) / 5.0 + 10.0, **APIS[api])
    st = _stepper(env, api)
    st.infos = env.reset(seed=seed)[1]
    agent_steps = [0]
    def run(k):
        for _ in range(k):
            agent_steps[0] += env.num_agents
            st()
    count = lambda: agent_steps[0]
run(warm)
vs0 = count(); n0 = len(env.agents)
print("READY", flush=True); wait("GO")
run(steps)
print("DONE", flush=True)
print("VS", count() - vs0, n0, len(env.agents), flush=True)
wait("END")
"""

def _until(proc, word):
    for line in proc.stdout:
        if line.strip() == word:
            return
    raise SystemExit(f"child ended before {word}: {proc.stderr.read()[-2000:]}")

def run_counted_child(tree, child, args, keep=None):
    """Run ``child`` (Python source) for ``tree`` under callgrind, its steps between its READY and DONE lines alone
    instrumented (``"{dir}"`` in ``args`` is the handshake directory); returns the exclusive instructions per
    object and the words of the line the child prints after DONE. ``keep``: copy callgrind's output there."""
    with tempfile.TemporaryDirectory() as d:
        env = dict(os.environ, PYTHONPATH=tree, PYTHONHASHSEED="0")
        proc = subprocess.Popen(["valgrind", "--tool=callgrind", "--instr-atstart=no",
                                 f"--callgrind-out-file={os.path.join(d, 'cg.out')}", sys.executable, "-c", child,
                                 *[x.replace("{dir}", d) for x in args]], env=env, cwd=d, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        _until(proc, "READY")
        subprocess.run(["callgrind_control", "-i", "on", str(proc.pid)], check=True, capture_output=True)
        open(os.path.join(d, "GO"), "w").close()
        _until(proc, "DONE")
        subprocess.run(["callgrind_control", "-i", "off", str(proc.pid)], check=True, capture_output=True)
        words = proc.stdout.readline().split()
        open(os.path.join(d, "END"), "w").close()
        proc.stderr.read()
        proc.wait()
        c = split(os.path.join(d, "cg.out"))
        if keep:
            shutil.copy(os.path.join(d, "cg.out"), keep)
    return c, words


def main():
    p = argparse.ArgumentParser()
    p.add_argument("tree"); p.add_argument("--api", default="dicts"); p.add_argument("--warm", type=int, default=2500)
    p.add_argument("--steps", type=int, default=50)
    p.add_argument("--env", default="ring", choices=("ring", "intersection"),
                   help="intersection: per agent-step instead of vehicle-step")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--keep", default=None, help="copy callgrind's output file here (for callgrind_annotate)")
    a = p.parse_args()
    c, vs_line = run_counted_child(a.tree, CHILD, [a.api, str(a.steps), str(a.warm), "{dir}", a.env, str(a.seed)], a.keep)
    g = Counter()
    for obj, v in c.items():
        g[group(obj)] += v
    total = sum(g.values())
    vs, n0, n1 = int(vs_line[1]), int(vs_line[2]), int(vs_line[3])
    unit = "vehicle-step" if a.env == "ring" else "agent-step"
    print(f"{a.env} ({a.api}, seed {a.seed}), {a.steps} policy steps after {a.warm}, {n0}-{n1} agents: "
          f"{total / a.steps:,.0f} instructions a policy step, {total / vs:,.0f} a {unit}")
    for k, v in g.most_common():
        print(f"  {k:45s} {v / total * 100:5.1f}%  {v / a.steps:12,.0f} a step")
    print(json.dumps({"env": a.env, "api": a.api, "seed": a.seed, "steps": a.steps, "warm": a.warm, "agents": [n0, n1], "per_step": total / a.steps,
                      "per_vehicle_step": total / vs, "by_object": {k: v / a.steps for k, v in g.items()}}))

if __name__ == "__main__":
    main()
