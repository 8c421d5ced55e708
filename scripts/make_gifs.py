"""Make the GIFs shown in the README and the docs (one per environment).

    SDL_VIDEODRIVER=dummy python scripts/make_gifs.py [--out docs/gifs]

Each is a short expert-driven run with the frame overlay (title, time,
legend), one frame every ``--every`` seconds, written with imageio and
checked to stay under ``--max-mb``. Prints one JSON line (file, frames,
bytes) last.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import gymnasium as gym  # noqa: E402
import imageio.v2 as imageio  # noqa: E402

import icv_envs  # noqa: E402,F401  (registers the ids)
from icv_envs import highway_formation_v0, intersection_v0  # noqa: E402


def _parallel(env, seconds, every, start=0.0):
    env.reset(seed=0)
    frames, k = [], max(1, round(every * env.core.config["policy_frequency"]))
    step = 0
    while not env.episode_over:
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
        step += 1
        t = step / env.core.config["policy_frequency"]
        if t >= start and step % k == 0:
            frames.append(env.render())
        if t >= seconds:
            break
    env.close()
    return frames


def highway_formation(every):
    env = highway_formation_v0.parallel_env(scenario="lane-drop", duration=32.0, render_mode="rgb_array")
    return _parallel(env, 32.0, every)


def highway_ramps(every):
    env = gym.make("icv_envs/HighwayRamps-v0", render_mode="rgb_array", config={"duration": 80.0})
    obs, info = env.reset(seed=0)
    frames, k, step = [], max(1, round(every * 5)), 0
    done = False
    while not done:
        obs, r, term, trunc, info = env.step(info["expert_action"])
        step += 1
        done = term or trunc
        if step % k == 0:
            frames.append(env.render())
    env.close()
    return frames


def intersection(every):
    env = intersection_v0.parallel_env(method="multi-vp", throughput=2000.0, duration=140.0, render_mode="rgb_array")
    return _parallel(env, 140.0, every, start=50.0)


MAKERS = {"highway_formation": highway_formation, "highway_ramps": highway_ramps, "intersection": intersection}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default="docs/gifs", help="output directory (default docs/gifs)")
    p.add_argument("--every", type=float, default=0.4, help="seconds between frames (default 0.4)")
    p.add_argument("--max-mb", type=float, default=2.0, help="fail if a GIF is larger (default 2 MB)")
    p.add_argument("--only", choices=sorted(MAKERS), default=None, help="make one GIF only")
    a = p.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    report = []
    for name, make in MAKERS.items():
        if a.only and name != a.only:
            continue
        frames = make(a.every if name != "intersection" else 2 * a.every)
        path = out / f"{name}.gif"
        imageio.mimsave(path, frames, duration=200, loop=0)  # 5 frames/s
        size = path.stat().st_size
        report.append({"file": str(path), "frames": len(frames), "bytes": size})
        print(f"{path}: {len(frames)} frames, {size / 1e6:.2f} MB", file=sys.stderr)
        if size > a.max_mb * 1e6:
            print(f"error: {path} is {size / 1e6:.2f} MB > --max-mb {a.max_mb}", file=sys.stderr)
            return 1
    print(json.dumps(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
