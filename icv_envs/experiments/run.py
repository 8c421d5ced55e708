"""Run one episode of an environment with a named policy and record metrics
(and optionally a video)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from icv_envs.envs.scenarios import SCENARIOS
from icv_envs._args import check_flag, check_float, check_int
from icv_envs.experiments._checks import check_run_config
from icv_envs.policies import make_policy

__all__ = ["run_highway_formation", "formation_errors", "ENVS"]

ENVS = ("highway-formation",)


def formation_errors(core) -> dict:
    """How far members are from their targets now: max |x - X_ref| [m],
    max |y - y_ref| [m], and how many members are not in their target lane."""
    w = core.world
    tr = w.traffic
    x_ref, lane_ref, _, member = w.manager.references(tr)
    if not member.any():
        return {"formation_error_x": None, "formation_error_y": None, "off_target_lane": 0, "members": 0}
    cx, cy = tr.center()
    ex = np.abs(cx - x_ref)[member]
    ey = np.abs(cy - lane_ref * w.road.lane_width)[member]
    lanes = w.road.lane_of(cy)[member]
    return {
        "formation_error_x": float(ex.max()),
        "formation_error_y": float(ey.max()),
        "off_target_lane": int((lanes != lane_ref[member]).sum()),
        "members": int(member.sum()),
    }


def run_highway_formation(
    scenario: str = "lane-drop",
    policy: str = "expert",
    seconds: float = 60.0,
    seed: int = 0,
    out: str | Path | None = None,
    video: bool = False,
    config: dict | None = None,
    progress: bool = False,
) -> dict:
    """Run ``scenario`` for ``seconds`` with ``policy``; returns the metrics
    dict and, with ``out``, writes ``metrics.json`` (and ``video.gif``)."""
    from icv_envs.envs.highway_formation_v0 import parallel_env

    if scenario not in SCENARIOS:
        raise ValueError(f"unknown scenario {scenario!r}; allowed: {sorted(SCENARIOS)}")
    check_float("seconds", seconds, 0)
    seed = check_int("seed", seed, 0)
    check_flag("video", video)
    if video and out is None:
        raise ValueError("video=True needs out (the directory video.gif is written to)")
    cfg = {"scenario": scenario, "duration": float(seconds)}
    cfg.update(check_run_config(config, {"scenario": "scenario (--scenario)", "duration": "seconds (--seconds)"}))
    pol = make_policy(policy, seed)
    env = parallel_env(render_mode="rgb_array" if video else None, **cfg)
    frames = []
    t0 = time.perf_counter()
    obs, infos = env.reset(seed=seed)
    steps = 0
    total_reward = 0.0
    n_steps = int(round(seconds * env.core.config["policy_frequency"]))
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n_steps, desc=f"{scenario}/{policy}", leave=False)
    if video:
        frames.append(env.render())
    while env.agents:
        actions = pol(env, obs, infos)
        obs, rew, term, trunc, infos = env.step(actions)
        total_reward += float(sum(rew.values()))
        steps += 1
        if bar is not None:
            bar.update(1)
        if video:
            frames.append(env.render())
    if bar is not None:
        bar.close()
    wall = time.perf_counter() - t0
    m = env.metrics()
    m.update(formation_errors(env.core))
    m.update(
        {
            "env": "highway-formation",
            "scenario": scenario,
            "policy": policy,
            "seed": seed,
            "steps": steps,
            "episode_return": total_reward,
            "reforms": env.core.world.manager.reforms,
            "wall_seconds": wall,
        }
    )
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        if video and frames:
            import imageio.v2 as imageio

            path = out / "video.gif"
            fps = env.core.config["policy_frequency"] * 2  # twice real time
            imageio.mimsave(path, frames, duration=1000.0 / fps, loop=0)
            m["video"] = str(path)
        (out / "metrics.json").write_text(json.dumps(m, indent=2))
    env.close()
    return m
