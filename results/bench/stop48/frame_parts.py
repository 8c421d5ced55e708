"""The intersection frame kernel's cost per call and its parts (stop 48): the calls of
multi-vp 2200 veh/h seed 0 captured over 400 steps after 100 s, then replayed whole
("full") and as drivers that run the integration alone (level 0) and add the motion
moments (1), the events (2), the PET update (6: events + PET), the collision pairs (8)
or everything (15); best of three passes, microseconds a call. Run for each tree:
``PYTHONPATH=<tree> python results/bench/stop48/frame_parts.py`` (stop 47: full 44.8 /
44.1 us, collisions +14-15, PET +3.4-9.9 over four runs; stop 48: 32.4 / 33.1, collisions +7, PET +2.7-2.8)."""
import sys, time, numpy as np, numba as nb
import os; sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "scripts"))
import bench_kernel_boundary as bk
from icv_envs.envs.intersection_v0 import parallel_env
from icv_envs.sim._kernels.physics import kinematic_substep_carry
from icv_envs.sim._kernels.intersection import box_collision_pairs_cs, intersection_events, arc_s1
from icv_envs.sim._kernels.stats import motion_record, pet_transitions
import icv_envs.sim.intersection_world as iw
env = parallel_env(method="multi-vp", throughput=2200.0, duration=450.0)
env.reset(seed=0); core = env.core
while core.world.time < 100 - 1e-9: env.step_rows(core.expert_actions())
calls = []
orig = iw.intersection_frames
def cap(*a):
    calls.append(bk._clone(a)); return orig(*a)
iw.intersection_frames = cap
for _ in range(400): env.step_rows(core.expert_actions())
iw.intersection_frames = orig

@nb.njit
def drive(level, n_frames, x, y, heading, speed, accel, steer, crashed, dt, wheelbase, v_max, t,
          vid, leg, mv, length, width, tlane, entered, departed, cleared, wrong_exit, exit_leg, plane,
          enter_time, out, app_dir, app_right, dep_right, exit_of, box_half, lane_width, n_lanes,
          off_margin, left_u, departure_length, P0, D0, P1, D1, L, arc, C, TH0, R, SGN,
          stopped_speed, m_count, m_s1, m_s2, pet_lo, pet_hi, pet_occ, pet_path, pet_busy):
    n = x.shape[0]; dummy = np.zeros(n); trig = np.empty((4, n)); c = 0.0
    for fr in range(n_frames):
        v_before = speed
        x, y, heading, speed, acc, st, _, cx, cy = kinematic_substep_carry(x, y, heading, speed, accel, steer, crashed, dummy, wheelbase, -1.0, dt, v_max, -1.0, trig, fr == 0)
        t = t + dt
        if level & 1:
            sv, sdv, sa, ns, _ = motion_record(vid, v_before, speed, acc, stopped_speed, m_count, m_s1, m_s2)
            c += sv
        if level & 2:
            (u, lat_leg, crash, new_wrong, clear_now, removed, left, pet_rows, pet_pid, pet_s, pet_arc,
             mb) = intersection_events(cx, cy, speed, leg, mv, length, crashed, tlane, entered, departed, cleared,
                                       wrong_exit, exit_leg, plane, enter_time, out, app_dir, app_right, dep_right,
                                       exit_of, box_half, lane_width, n_lanes, off_margin, left_u, departure_length, t,
                                       P0, D0, P1, D1, L, arc)
            if level & 4:
                npet = pet_rows.shape[0]
                pvid = np.empty(npet, dtype=np.int64)
                plen = np.empty(npet)
                for q in range(npet):
                    r = pet_rows[q]
                    pvid[q] = vid[r]
                    plen[q] = length[r]
                    if pet_arc[q]:
                        pet_s[q] = arc_s1(pet_pid[q], cx[r], cy[r], C, TH0, R, SGN)
                lft, ent, pet_busy = pet_transitions(pvid, pet_pid, pet_s, plen, pet_lo, pet_hi, pet_occ, pet_path, pet_busy)
        if level & 8:
            i, j = box_collision_pairs_cs(cx, cy, heading, trig[0], trig[1], length, width, box_half)
            c += i.shape[0]
    return c

def T(level, argsets):
    best = 1e9
    for r in range(3):
        cl = [bk._clone(a) for a in argsets]
        t = time.perf_counter()
        for a in cl: drive(level, *a[:55])
        best = min(best, (time.perf_counter() - t) / len(cl) * 1e6)
    return best
def TF(argsets):
    best = 1e9
    for r in range(3):
        cl = [bk._clone(a) for a in argsets]
        t = time.perf_counter()
        for a in cl: orig(*a)
        best = min(best, (time.perf_counter() - t) / len(cl) * 1e6)
    return best
drive(15, *bk._clone(calls[0])[:55])
for _ in range(2):
    print("full", round(TF(calls), 1), {lv: round(T(lv, calls), 1) for lv in (0, 1, 2, 6, 8, 15)})
