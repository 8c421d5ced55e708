"""Compiled-kernel calls per batched world-step (stop 40): every numba
dispatcher imported by an icv_envs module is wrapped to count its calls,
array and scalar arguments and returned arrays, over 50 steps of 16
HighwayFormation worlds of 20 agents (after 50 untimed). Run from outside
the checkout: ``PYTHONPATH=<tree> python count_kernel_calls.py 0|1``
(0: zero actions, 1: the expert's). The "est" column weighs them with this
machine's per-item costs (53 ns an array argument, 20 ns a scalar, 350 ns a
returned array, 50 ns a call)."""
import sys, collections, numpy as np
from numba.core.registry import CPUDispatcher
expert = sys.argv[1] == "1"
from icv_envs.vector import BatchedWorlds
B=16
bw = BatchedWorlds(B, config={"vehicles_count": 20, "initial_position": None}, seed=0, expert=expert)
bw.reset()
act = (lambda: bw.expert_actions) if expert else (lambda: np.zeros((B, bw.K, 2), dtype=np.float32))
for _ in range(50): bw.step(act())
calls = collections.Counter(); arrs = collections.Counter(); scal = collections.Counter(); rets = collections.Counter()
def wrap(name, d):
    def g(*a):
        r = d(*a)
        calls[name] += 1
        arrs[name] += sum(isinstance(x, np.ndarray) for x in a)
        scal[name] += sum(not isinstance(x, np.ndarray) for x in a)
        if isinstance(r, tuple): rets[name] += sum(isinstance(x, np.ndarray) for x in r)
        elif isinstance(r, np.ndarray): rets[name] += 1
        return r
    return g
for mname, mod in list(sys.modules.items()):
    if not mname.startswith("icv_envs") or mod is None: continue
    for k, v in list(vars(mod).items()):
        if isinstance(v, CPUDispatcher):
            setattr(mod, k, wrap(k, v))
N=50
for _ in range(N): bw.step(act())
W = N*B
print(f"per world-step: calls {sum(calls.values())/W:.1f}, array args {sum(arrs.values())/W:.1f}, scalar args {sum(scal.values())/W:.1f}, returned arrays {sum(rets.values())/W:.1f}")
for k in sorted(calls, key=lambda k: -(arrs[k]*0.053+scal[k]*0.02+rets[k]*0.35)):
    print(f"{k:32s} calls {calls[k]/W:5.2f} arr {arrs[k]/W:6.1f} scal {scal[k]/W:5.1f} ret {rets[k]/W:5.1f}  est {(arrs[k]*0.053+scal[k]*0.02+rets[k]*0.35+calls[k]*0.05)/W:5.2f} us")
