"""Where a step of the paper's ring goes (issue 10): HighwayRamps, VGR 1/3,
formation expert through the PettingZoo parallel API, after a warm-up to
steady state (~450 vehicles), profiled with cProfile; prints the share of
the step in each part the README's Speed section names.

    PYTHONPATH=$PWD python scripts/profile_ring_step.py [--warmup 500] [--steps 250]

cProfile slows Python-level code more than numpy calls, so compare shares
between trees, not absolute times.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--warmup", type=float, default=500.0, help="simulated seconds before profiling")
    p.add_argument("--steps", type=int, default=250, help="policy steps profiled")
    a = p.parse_args()
    from tqdm import tqdm

    from icv_envs.envs import highway_ramps_v0

    env = highway_ramps_v0.parallel_env(vgr=1 / 3, duration=a.warmup + a.steps / 5.0 + 1.0)
    env.reset(seed=0)
    for _ in tqdm(range(int(a.warmup * 5)), desc="warm-up", mininterval=5.0):
        ex = env.expert_actions()
        env.step({ag: ex[ag] for ag in env.agents})
    n0 = len(env.agents)

    def run():
        for _ in range(a.steps):
            ex = env.expert_actions()
            env.step({ag: ex[ag] for ag in env.agents})

    prof = cProfile.Profile()
    prof.runcall(run)
    st = pstats.Stats(prof)
    total = max(v[3] for v in st.stats.values())  # cumulative time of run()
    parts = {
        "formation layer update (FormationManager.update)": "formations.py:update",
        "formation expert (FormationExpert.compute)": "formation_expert.py:compute",
        "physics frames (World.substeps: every substep of the ring runs inside it)": "world.py:substeps",
        "observations (_observe_rows)": "base.py:_observe_rows",
        "features (_features)": "highway_rows.py:_features",
        "rewards (_rewards_rows)": "highway_rows.py:_rewards_rows",
        "info dicts (_info_dicts + _label_infos)": ("dict_edge.py:_info_dicts", "dict_edge.py:_label_infos"),
        "obs/reward/termination dicts (_agent_dicts)": "dict_edge.py:_agent_dicts",
        "action check (_check_actions)": "dict_edge.py:_check_actions",
    }

    def cum(key: str) -> float:
        fname, func = key.split(":")
        return sum(v[3] for (f, _, fn), v in st.stats.items() if f.endswith(fname) and fn == func)

    print(f"{a.steps} policy steps at {n0}-{len(env.agents)} vehicles, {total:.2f} s under cProfile")
    for label, key in parts.items():
        keys = key if isinstance(key, tuple) else (key,)
        print(f"  {100 * sum(cum(k) for k in keys) / total:5.1f}%  {label}")


if __name__ == "__main__":
    main()
