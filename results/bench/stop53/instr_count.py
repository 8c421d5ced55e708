"""Instructions per batched world-step, counted by valgrind's callgrind: a measure this host's noise does not move
(stop 53; the host has no hardware counters, and its CPU time moved 2x between repetitions of one run).

One process per (tree, kind): 16 HighwayFormation worlds of 20 agents, seed 0; a first batch runs ``--warm`` steps of
the kind's actions (it loads every compiled kernel those steps reach from numba's cache), then a second batch, reset,
runs ``--steps`` steps of the same actions, and only those are counted: the process runs under ``valgrind
--tool=callgrind --instr-atstart=no`` and this script switches the instrumentation on (``callgrind_control -i on``)
just before them and off just after (the child waits for a file between; its polls add a few thousand
instructions). PYTHONHASHSEED is fixed.

    python results/bench/stop53/instr_count.py REF_TREE TEST_TREE [--kinds noisy,uniform,zero] [--steps 100]

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
from icv_envs.vector import BatchedWorlds
kind, steps, warm, d = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
def actions(rng, shape):
    if kind == "noisy":
        return np.clip(rng.normal(0.0, 0.3, shape), -1.0, 1.0).astype(np.float32)
    if kind == "uniform":
        return rng.uniform(-1.0, 1.0, shape).astype(np.float32)
    return np.zeros(shape, dtype=np.float32)
def wait(name):
    while not os.path.exists(os.path.join(d, name)):
        time.sleep(0.01)
for timed, n in ((False, warm), (True, steps)):
    bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0)
    bw.reset()
    rng = np.random.default_rng(0)
    acts = [actions(rng, (16, bw.K, 2)) for _ in range(n)]
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


def count(tree: str, kind: str, steps: int, warm: int) -> int:
    with tempfile.TemporaryDirectory() as d:
        env = dict(os.environ, PYTHONPATH=tree, PYTHONHASHSEED="0")
        proc = subprocess.Popen(["valgrind", "--tool=callgrind", "--instr-atstart=no",
                                 f"--callgrind-out-file={os.path.join(d, 'cg.out')}", sys.executable, "-c", CHILD,
                                 kind, str(steps), str(warm), d], env=env, cwd=d, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        _until(proc, "READY")
        subprocess.run(["callgrind_control", "-i", "on", str(proc.pid)], check=True, capture_output=True)
        open(os.path.join(d, "GO"), "w").close()
        _until(proc, "DONE")
        subprocess.run(["callgrind_control", "-i", "off", str(proc.pid)], check=True, capture_output=True)
        open(os.path.join(d, "END"), "w").close()
        err = proc.stderr.read()
        proc.wait()
        m = re.search(r"Collected\s*:\s*(\d+)", err)
        if proc.returncode or m is None:
            raise SystemExit(f"valgrind failed ({tree}, {kind}):\n{err[-2000:]}")
        return int(m.group(1))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("reference")
    p.add_argument("test")
    p.add_argument("--kinds", default="noisy,uniform,zero")
    p.add_argument("--steps", type=int, default=100)
    p.add_argument("--warm", type=int, default=100)
    a = p.parse_args()
    kinds = a.kinds.split(",")
    jobs = [(t, k) for k in kinds for t in (a.reference, a.test)]
    res = {"steps": a.steps, "warm": a.warm, "worlds": 16, "vehicles": 20, "kinds": {}}
    with ThreadPoolExecutor(2) as ex:
        got = dict(zip(jobs, ex.map(lambda j: count(j[0], j[1], a.steps, a.warm), jobs)))
    for k in kinds:
        per = {name: got[(t, k)] / (16 * a.steps) for name, t in (("reference", a.reference), ("test", a.test))}
        res["kinds"][k] = {**per, "ratio": per["reference"] / per["test"]}
        print(f"{k:8s} instructions per world-step: reference {per['reference']:,.0f}, test {per['test']:,.0f}, "
              f"reference / test {per['reference'] / per['test']:.3f}", flush=True)
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
