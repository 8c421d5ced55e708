"""What moving the step's transcendental calls from NumPy into the compiled
code (libm) would give (stop 49): a prototype, not the package's code.

Two of the batched highway world-step's seams where a kernel stops only so
that NumPy can take a power or an exp are joined in one compiled call each,
with libm's ``pow`` and ``exp``:

* ``JoinPlans._eval``: ``profile_gather`` + ``np.power(tc, [3, 4, 5])`` +
  ``quintic_rows`` -> one kernel (``profile_eval``);
* ``HighwayRows._reward_total``: ``np.where(member, np.exp(expo), 0)`` and
  ``partial + w * form`` -> one kernel (``reward_total``).

Twin BatchedWorlds (16 HighwayFormation worlds of 20 agents, zero actions,
seed 0) step in one process, alternately: twin A with the package's code,
twin B with the prototype patched onto its instances. Every step's
observations, rewards and masks are compared (bit for bit); the time of each
twin's steps is summed. Run it as is (NumPy at this machine's level) and with
the reference fingerprints' cap
``NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL"``: under the cap NumPy's exp
and power are libm's (``libm_vs_numpy.py``), so the twins must agree.

    python results/bench/stop49/libm_prototype.py [--steps 300] [--expert]
"""
import argparse
import hashlib
import json
import math
import os
import time
import types

import numba as nb
import numpy as np

from icv_envs.vector import BatchedWorlds


@nb.njit(cache=True)
def profile_eval(vid, time, t0_tab, T_tab, fd_tab, fv_tab, fa_tab, d0, v0, a0, c3, c4, c5):
    """profile_gather + the powers (libm) + quintic_rows, one pass, the same operations."""
    n = vid.shape[0]
    P = np.empty((3, n))
    for i in range(n):
        k = vid[i]
        t = time - t0_tab[k]
        T = T_tab[k]
        if t < T:
            x = t if t > 0.0 else 0.0
            ti = x if x < T else T
            t3, t4, t5 = ti ** 3.0, ti ** 4.0, ti ** 5.0
            t2 = ti * ti
            d, v, a = d0[k], v0[k], a0[k]
            p3, p4, p5 = c3[k], c4[k], c5[k]
            P[0, i] = d + v * ti + 0.5 * a * t2 + p3 * t3 + p4 * t4 + p5 * t5
            P[1, i] = v + a * ti + 3.0 * p3 * t2 + 4.0 * p4 * t3 + 5.0 * p5 * t4
            P[2, i] = a + 6.0 * p3 * ti + 12.0 * p4 * t2 + 20.0 * p5 * t3
        else:
            P[0, i] = fd_tab[k]
            P[1, i] = fv_tab[k]
            P[2, i] = fa_tab[k]
    return P


@nb.njit(cache=True)
def reward_total(member, expo, partial, w):
    """np.where(member, np.exp(expo), 0.0) and partial + w * form, libm's exp."""
    n = expo.shape[0]
    out = np.empty((2, n))
    for i in range(n):
        f = math.exp(expo[i]) if member[i] else 0.0
        out[1, i] = f
        out[0, i] = partial[i] + w * f
    return out


def _eval(self, vid, time):
    P = profile_eval(vid, float(time), self.t0, self.T, self.fd, self.fv, self.fa, self.d0, self.v0, self.a0,
                     self.c3, self.c4, self.c5)
    return P[0], P[1], P[2]


def _reward_total(self, terms):
    progress, safety, comfort, expo, member, partial = terms
    out = reward_total(member, expo, partial, float(self.config["reward"]["formation"]))
    return out[0], {"progress": progress, "safety": safety, "comfort": comfort, "formation": out[1]}


def patch(bw):
    for env in bw.envs:
        core = env.core
        core._reward_total = types.MethodType(_reward_total, core)
        plans = core.world.manager._plans
        plans._eval = types.MethodType(_eval, plans)


def make(expert):
    bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0, expert=expert)
    bw.reset()
    return bw


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--expert", action="store_true")
    a = p.parse_args()
    A, B = make(a.expert), make(a.expert)
    patch(B)
    zeros = np.zeros((16, A.K, 2), dtype=np.float32)
    tA = tB = 0.0
    first_diff = None
    hA, hB = hashlib.sha256(), hashlib.sha256()
    for s in range(a.steps + 20):
        outs = []
        order = (A, B) if s % 2 == 0 else (B, A)
        for bw in order:
            act = bw.expert_actions if a.expert else zeros
            t0 = time.perf_counter()
            out = bw.step(act)
            dt = time.perf_counter() - t0
            if s >= 20:  # (the first 20 steps load the kernels)
                if bw is A:
                    tA += dt
                else:
                    tB += dt
            outs.append((bw, out))
        oA = [o for bw, o in outs if bw is A][0]
        oB = [o for bw, o in outs if bw is B][0]
        for h, o in ((hA, oA), (hB, oB)):
            for arr in o[:5]:
                h.update(np.ascontiguousarray(arr).tobytes())
        if first_diff is None and not all(np.array_equal(x, y) for x, y in zip(oA[:5], oB[:5])):
            first_diff = s
    ws = a.steps * 16
    print(json.dumps({"cap": os.environ.get("NPY_DISABLE_CPU_FEATURES", ""), "expert": a.expert, "steps": a.steps,
                      "package_us_per_world_step": round(tA / ws * 1e6, 2),
                      "prototype_us_per_world_step": round(tB / ws * 1e6, 2), "ratio": round(tA / tB, 4),
                      "identical": first_diff is None, "first_step_differing": first_diff,
                      "hash_package": hA.hexdigest()[:16], "hash_prototype": hB.hexdigest()[:16]}))


if __name__ == "__main__":
    main()
