"""line_profiler over the intersection's hot Python (array path; stop 47).
Prints per function total time; --lines prints the line tables."""
import sys
from line_profiler import LineProfiler
from icv_envs.envs.intersection_v0 import parallel_env
from icv_envs.envs import agents_step, intersection_rows, intersection as ienv
from icv_envs.policies import virtual_platoon as vp, regrouping as rg, platoon_expert as pe, platoon_control as pc, platoon_common as pcm
from icv_envs.sim import intersection_world as iw

env = parallel_env(method="multi-vp", throughput=2200.0, duration=260)
env.reset(seed=0)
while env.core.world.time < 100 - 1e-9:
    env.step_rows(env.core.expert_actions())
lp = LineProfiler()
E = type(env.core.expert)
funcs = [iw.IntersectionWorld.substeps, iw.IntersectionWorld.route, iw.Fleet.rows, E._references, E.tree, E._sub_table, E._adjusting, E._merging,
         E._approach_and_division, E._start_lane_changes, E._prune, E._lane_change_progress, E._coordinate,
         E._detach_inverted, E.update, E._envelope, E._envelope_pairs, E._longitudinal, E.compute, E._steering,
         pcm.Corridors.__init__, pcm.Corridors._inputs, pcm.group_rows, E._member_rows, E._signals,
         type(env.core)._post_rows, type(env.core)._reward_args, type(env.core)._feature_args,
         agents_step.IcvAgentsEnv._ma_advance if hasattr(agents_step, "IcvAgentsEnv") else type(env.core)._ma_advance,
         type(env.core)._react, type(env.core)._spawn_due, type(env.core)._advance]
for f in funcs:
    lp.add_function(f)
lp.enable_by_count()
n = 0
while env.core.world.time < 250 - 1e-9:
    env.step_rows(env.core.expert_actions()); n += 1
lp.disable_by_count()
st = lp.get_stats()
rows = []
for (fn, line, name), timings in st.timings.items():
    tot = sum(t[2] for t in timings) * st.unit
    rows.append((tot, name, fn.split("/")[-1], line))
for tot, name, fn, line in sorted(rows, reverse=True):
    print(f"{tot / n * 1e6:8.1f} us/step  {name} ({fn}:{line})")
if "--lines" in sys.argv:
    lp.print_stats(output_unit=1e-6, stripzeros=True)
