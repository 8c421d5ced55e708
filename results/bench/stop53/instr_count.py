"""Instructions per batched world-step, counted by valgrind's callgrind: a measure this host's noise does not move
(stop 53; the host has no hardware counters, and its CPU time moved 2x between repetitions of one run).

One process per (tree, kind): 16 HighwayFormation worlds of 20 agents, seed 0 (``--worlds``, ``--vehicles``, ``--seed``); a first batch runs ``--warm`` steps of
the kind's actions (it loads every compiled kernel those steps reach from numba's cache), then a second batch, reset,
runs ``--steps`` steps of the same actions, and only those are counted: the process runs under ``valgrind
--tool=callgrind --instr-atstart=no`` and this script switches the instrumentation on (``callgrind_control -i on``)
just before them and off just after (the child waits for a file between; its polls add a few thousand
instructions). PYTHONHASHSEED is fixed.

    python results/bench/stop53/instr_count.py REF_TREE TEST_TREE [--kinds noisy,uniform,zero] [--steps 100]
    python results/bench/stop53/instr_count.py REF_TREE TEST_TREE --kinds ring --warm 2500 --steps 50
    python results/bench/stop53/instr_count.py REF_TREE TEST_TREE --kinds intersection --steps 200

Kinds ``ring`` and ``intersection`` (per policy step): the loops of the ring's and the intersection's benches
(``scripts/bench_trees.py --case ring`` / ``intersection``), ``--warm`` policy steps of the ring uncounted first.

About two minutes a process, two at a time. Prints a line per kind and a JSON line.
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

CHILD = """
import os, sys, time
import numpy as np
kind, steps, warm, d = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
B, N, seed = (int(v) for v in sys.argv[5:8])
def wait(name):
    while not os.path.exists(os.path.join(d, name)):
        time.sleep(0.01)
if kind == "ring":
    # the paper's ring, HighwayRamps VGR 1/3, the formation expert through PettingZoo's dicts (the ring bench's
    # loop): ``warm`` policy steps, then ``steps`` counted
    from icv_envs.envs.highway_ramps_v0 import parallel_env
    env = parallel_env(vgr=1.0 / 3.0, duration=600.0, method="formation")
    env.reset(seed=0)
    for k in range(warm + steps):
        if k == warm:
            print("READY", flush=True)
            wait("GO")
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    print("DONE", flush=True)
    wait("END")
    sys.exit(0)
if kind == "intersection":
    # multi-vp at 2200 veh/h through PettingZoo's dicts, every vehicle an agent with the expert's action from
    # its info (the intersection bench's loop): the zones filled to 60 vehicles, then ``steps`` counted
    from icv_envs.envs.intersection_v0 import parallel_env
    env = parallel_env(method="multi-vp", throughput=2200.0, duration=300.0 + steps / 5.0 + 10.0)
    obs, infos = env.reset(seed=0)
    while len(env.agents) < 60 and env.core.world.time < 300:
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
    print("READY", flush=True)
    wait("GO")
    for _ in range(steps):
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
    print("DONE", flush=True)
    wait("END")
    sys.exit(0)
from icv_envs.vector import BatchedWorlds
def actions(rng, shape):
    if kind == "noisy":
        return np.clip(rng.normal(0.0, 0.3, shape), -1.0, 1.0).astype(np.float32)
    if kind == "uniform":
        return rng.uniform(-1.0, 1.0, shape).astype(np.float32)
    return np.zeros(shape, dtype=np.float32)
for timed, n in ((False, warm), (True, steps)):
    bw = BatchedWorlds(B, config={"vehicles_count": N, "initial_position": None}, seed=seed)
    bw.reset()
    rng = np.random.default_rng(seed)
    acts = [actions(rng, (B, bw.K, 2)) for _ in range(n)]
    if timed:
        print("READY", flush=True)
        wait("GO")
    for a in acts:
        bw.step(a)
print("DONE", flush=True)
wait("END")
"""


def _until(proc, word: str) -> None:
    for line in proc.stdout:
        if line.strip() == word:
            return
    raise SystemExit(f"the child ended before {word}: {proc.stderr.read()[-2000:]}")


def run_counted(tree: str, kind: str, steps: int, warm: int, d: str, worlds: int = 16, vehicles: int = 20,
                seed: int = 0) -> str:
    """Run the child for ``tree`` and ``kind`` under callgrind in directory ``d``, its counted steps alone
    instrumented; the profile is ``d/cg.out``. Returns valgrind's report (stderr)."""
    env = dict(os.environ, PYTHONPATH=tree, PYTHONHASHSEED="0")
    proc = subprocess.Popen(["valgrind", "--tool=callgrind", "--instr-atstart=no",
                             f"--callgrind-out-file={os.path.join(d, 'cg.out')}", sys.executable, "-c", CHILD,
                             kind, str(steps), str(warm), d, str(worlds), str(vehicles), str(seed)], env=env, cwd=d, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    _until(proc, "READY")
    subprocess.run(["callgrind_control", "-i", "on", str(proc.pid)], check=True, capture_output=True)
    open(os.path.join(d, "GO"), "w").close()
    _until(proc, "DONE")
    subprocess.run(["callgrind_control", "-i", "off", str(proc.pid)], check=True, capture_output=True)
    open(os.path.join(d, "END"), "w").close()
    err = proc.stderr.read()
    proc.wait()
    if proc.returncode:
        raise SystemExit(f"valgrind failed ({tree}, {kind}):\n{err[-2000:]}")
    return err


def count(tree: str, kind: str, steps: int, warm: int, worlds: int = 16, vehicles: int = 20, seed: int = 0) -> int:
    with tempfile.TemporaryDirectory() as d:
        err = run_counted(tree, kind, steps, warm, d, worlds, vehicles, seed)
        m = re.search(r"Collected\s*:\s*(\d+)", err)
        if m is None:
            raise SystemExit(f"no count in valgrind's report ({tree}, {kind}):\n{err[-2000:]}")
        return int(m.group(1))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("reference")
    p.add_argument("test")
    p.add_argument("--kinds", default="noisy,uniform,zero")
    p.add_argument("--steps", type=int, default=100)
    p.add_argument("--warm", type=int, default=100, help="batched kinds: the first batch's steps; ring: policy "
                   "steps before the counted ones (2500: the ring bench's 500 s)")
    p.add_argument("--worlds", type=int, default=16, help="batched kinds: worlds")
    p.add_argument("--vehicles", type=int, default=20, help="batched kinds: agents per world")
    p.add_argument("--seed", type=int, default=0, help="batched kinds: the batch's and the actions' seed")
    a = p.parse_args()
    kinds = a.kinds.split(",")
    jobs = [(t, k) for k in kinds for t in (a.reference, a.test)]
    res = {"steps": a.steps, "warm": a.warm, "kinds": {}}
    if set(kinds) - {"ring", "intersection"}:
        res.update(worlds=a.worlds, vehicles=a.vehicles, seed=a.seed)  # (the batched kinds')
    with ThreadPoolExecutor(2) as ex:
        got = dict(zip(jobs, ex.map(lambda j: count(j[0], j[1], a.steps, a.warm, a.worlds, a.vehicles, a.seed),
                                    jobs)))
    for k in kinds:
        unit = "policy step" if k in ("ring", "intersection") else "world-step"
        div = a.steps if k in ("ring", "intersection") else a.worlds * a.steps
        per = {name: got[(t, k)] / div for name, t in (("reference", a.reference), ("test", a.test))}
        res["kinds"][k] = {**per, "unit": f"instructions per {unit}", "ratio": per["reference"] / per["test"]}
        print(f"{k:12s} instructions per {unit}: reference {per['reference']:,.0f}, test {per['test']:,.0f}, "
              f"reference / test {per['reference'] / per['test']:.3f}", flush=True)
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
