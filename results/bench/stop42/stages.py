"""Stage timers on the intersection step (stop 41; stop 42: Corridors from platoon_common): wraps the env's and the expert's stages with
perf_counter and prints microseconds per step over 600 steps of multi-vp at 2200 veh/h after the zones hold
60 vehicles. The timers add their own cost. (Stop 42: the observation, feature and reward
hooks are not wrapped: a wrapped hook sends _post_rows to the separate calls.) Run per tree: PYTHONPATH=<tree> python stages.py"""
import time, collections
import icv_envs.envs.base as BASE, icv_envs.envs.intersection as I
import icv_envs.policies.platoon_expert as PE
import icv_envs.sim.intersection_world as IW, icv_envs.policies.platoon_control as PC, icv_envs.policies.platoon_common as PCm
acc = collections.Counter()
def timed(cls, name, label):
    f = getattr(cls, name, None)
    if f is None: return
    def g(*a, **k):
        t = time.perf_counter_ns(); r = f(*a, **k); acc[label] += time.perf_counter_ns() - t; return r
    setattr(cls, name, g)
T = [(BASE.IcvAgentsEnv, "ma_step", "0 ma_step"), (I.IntersectionEnv, "_react", "1 react"),
     (PE.PlatoonExpert, "update", "1b update"), (I.IntersectionEnv, "_spawn_due", "1a spawn"),
     (BASE.IcvAgentsEnv, "_advance", "2 advance"), (IW.IntersectionWorld, "substeps", "2a substeps"),
     (I.IntersectionEnv, "_post_rows", "3 post_rows"),
     (BASE.IcvAgentsEnv, "expert_actions", "4 expert_actions"), (PC.PlatoonControl if hasattr(PC, "PlatoonControl") else PE.PlatoonExpert, "compute", "4a compute"),
     (BASE.IcvAgentsEnv, "_check_actions", "5 check"),
     (IW.IntersectionWorld, "route", "6 route"),
     (PE.PlatoonExpert, "_prune", "u0 prune"), (PE.PlatoonExpert, "_lane_change_progress", "u1 lcp"),
     (PE.PlatoonExpert, "_approach_and_division", "u2 div"), (PE.PlatoonExpert, "_adjusting", "u3 adj"),
     (PE.PlatoonExpert, "_merging", "u4 merge"), (PE.PlatoonExpert, "_reroute_stuck", "u5 reroute"),
     (PE.PlatoonExpert, "_coordinate", "u6 coord"), (PE.PlatoonExpert, "_start_lane_changes", "u7 lcstart"),
     (PE.PlatoonExpert, "_references", "u8 refs"), (PE.PlatoonExpert, "tree", "u8a tree"),
     (PE.PlatoonExpert, "_detach_inverted", "u6a detach"), (PE.PlatoonExpert, "_anticipate", "u8b anticip"),
     (PE.PlatoonExpert, "_member_rows", "x member_rows"), (PCm.Corridors, "__init__", "x corridors")]
for c, n, l in T: timed(c, n, l)
from icv_envs.envs.intersection_v0 import parallel_env
env = parallel_env(method="multi-vp", throughput=2200.0, duration=600.0)
obs, infos = env.reset(seed=0)
while len(env.agents) < 60 and env.core.world.time < 300:
    obs, rew, term, trunc, infos = env.step({ag: infos[ag]["expert_action"] for ag in env.agents})
for _ in range(100):
    obs, rew, term, trunc, infos = env.step({ag: infos[ag]["expert_action"] for ag in env.agents})
acc.clear(); n = 600; t0 = time.perf_counter_ns(); na = 0
for _ in range(n):
    na += len(env.agents)
    obs, rew, term, trunc, infos = env.step({ag: infos[ag]["expert_action"] for ag in env.agents})
tot = time.perf_counter_ns() - t0
print(f"total {tot/n/1000:.0f} us/step, {na/n:.1f} agents")
for k in sorted(acc): print(f"{k:20s} {acc[k]/n/1000:7.1f} us/step")
