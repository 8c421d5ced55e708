"""Stop 46: a prototype of the observations and rewards of 16 batched worlds in one pass (formation_post_rows world by
world inside one compiled call, the inputs gathered from the worlds), against each world's own _post_rows on the same
state: the same numbers (printed True), and the time of each per world. Not built into the package: it saves about
6 of 23 us per world. Run: PYTHONPATH=<tree> python proto_post.py"""
import numpy as np, time, numba as nb
from icv_envs.vector import BatchedWorlds
from icv_envs.sim._kernels.observation import formation_post_rows

@nb.njit(cache=True)
def post_many(offs, cx, cy, speed, ch, sh, x_ref, lane_ref, v_ref, member, gap, crashed, ua, road, rew_c, nb_c, opts, o_period, F):
    nw = offs.shape[0] - 1
    N = offs[nw]
    T = np.empty((5, N)); M = np.empty(N, np.bool_); O = np.empty((N, opts[1], F), np.float32)
    for b in range(nw):
        o0 = offs[b]; o1 = offs[b + 1]
        rows = np.arange(o1 - o0)
        t, m, o = formation_post_rows(cx[o0:o1], cy[o0:o1], speed[o0:o1], ch[o0:o1], sh[o0:o1], x_ref[o0:o1], lane_ref[o0:o1], v_ref[o0:o1], member[o0:o1], *road,
                                      rows, speed[o0:o1], rew_c[0], gap[o0:o1], crashed[o0:o1], ua[o0:o1], rew_c[1], rew_c[2], rew_c[3], rew_c[4], rew_c[5], *nb_c, *opts, o_period)
        T[:, o0:o1] = t; M[o0:o1] = m; O[o0:o1] = o
    return T, M, O

bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0)
bw.reset(); acts = np.zeros(bw._act_shape)
for _ in range(30): bw.step(acts)
cores = [e.core for e in bw.envs]
def per_world():
    out = []
    for c in cores:
        n = c._vehicles().n
        out.append(c._post_rows(np.arange(n), c._vehicles().crashed.copy()))
    return out
def batched():
    args = []
    for c in cores:
        n = c._vehicles().n
        rows = np.arange(n)
        fa = c._feature_args(); ra = c._reward_args(rows, c._vehicles().crashed.copy())
        args.append((fa, ra))
    offs = np.zeros(17, np.int64); np.cumsum([len(a[0][0]) for a in args], out=offs[1:])
    cat = np.concatenate
    f = [cat([a[0][k] for a in args]) for k in range(9)]
    gap = cat([a[1][3] for a in args]); cr = cat([a[1][4] for a in args]); ua = cat([a[1][5] for a in args])
    c0 = cores[0]; fa0, ra0 = args[0]
    opts = c0._obs_type.kernel_options()
    road = fa0[9:]
    rew_c = (ra0[2], ra0[6], ra0[7], ra0[8], ra0[9], ra0[10])
    nb_c = c0._neighbour_args(opts[1] - 1, c0._obs_type.pd)
    T, M, O = post_many(offs, *f, gap, cr, ua, road, rew_c, nb_c, opts, float(c0._wrap_period()), len(opts[0]))
    form = np.where(M, np.exp(T[3]), 0.0)
    total = T[4] + c0.config["reward"]["formation"] * form
    return [(total[offs[b]:offs[b+1]], O[offs[b]:offs[b+1]]) for b in range(16)]
a = per_world(); b = batched()
print(all(x[0].tobytes() == y[0].tobytes() and x[2].tobytes() == y[1].tobytes() for x, y in zip(a, b)))
for f in (per_world, batched):
    t = time.process_time()
    for _ in range(300): f()
    print(f.__name__, (time.process_time() - t) / 300 / 16 * 1e6, "us per world")
