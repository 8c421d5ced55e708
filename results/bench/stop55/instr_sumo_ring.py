"""Stop 55: instructions per vehicle-step of SUMO on the bench's ring (libsumo in this process, the ring of
``icv_envs.experiments.sumo_ring.SumoRing``: 445 vehicles, as the ring bench builds it after our 600 s), counted
by callgrind with only the counted steps instrumented (the handshake of ``instr_split_ring.py``): the
noise-free counterpart of ``icv-envs bench highway-ramps --vs-sumo``'s CPU-time ratio.

    python results/bench/stop55/instr_sumo_ring.py TREE [--vehicles 445] [--warm 500] [--steps 500]
"""
import argparse, json, os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from instr_split_ring import run_counted_child  # noqa: E402  (the same handshake)

CHILD = """
import os, sys, time
n, steps, warm, d = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
from icv_envs.experiments.sumo_ring import SumoRing
def wait(name):
    while not os.path.exists(os.path.join(d, name)):
        time.sleep(0.01)
ring = SumoRing(n, seed=0)
ring.step(warm)
print("READY", flush=True); wait("GO")
r = ring.step(steps)
print("DONE", flush=True)
print("VS", r["vehicle_steps"], r["vehicles"], flush=True)
wait("END")
ring.close()
"""


def main():
    p = argparse.ArgumentParser()
    p.add_argument("tree"); p.add_argument("--vehicles", type=int, default=445)
    p.add_argument("--warm", type=int, default=500); p.add_argument("--steps", type=int, default=500)
    a = p.parse_args()
    c, vs_line = run_counted_child(a.tree, CHILD, [str(a.vehicles), str(a.steps), str(a.warm), "{dir}"])
    total = sum(c.values())
    vs = int(vs_line[1])
    print(f"SUMO ring, {a.vehicles} vehicles, {a.steps} steps after {a.warm}: {total / vs:,.0f} instructions a vehicle-step")
    for k, v in c.most_common(5):
        print(f"  {os.path.basename(k) or k:45s} {v / total * 100:5.1f}%")
    print(json.dumps({"vehicles": a.vehicles, "steps": a.steps, "warm": a.warm, "vehicle_steps": vs,
                      "per_vehicle_step": total / vs}))

if __name__ == "__main__":
    main()
