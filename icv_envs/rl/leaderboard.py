"""The leaderboard: every policy on every task, on fixed held-out seeds.

    icv-envs leaderboard [--out results/leaderboard] [--models results/learned] [--tasks lane-drop,...]
                         [--episodes N] [--seed 1000000] [--reps 2000] [--reuse]
    run_leaderboard(out, models_dir, tasks=None, episodes=None, seed=..., reps=..., reuse=False) -> rows

Tasks (:data:`TASKS`; env, config, default episodes):

| task | env | config | episodes |
|---|---|---|---:|
| ``lane-drop`` | ``icv_envs/highway_formation-v0`` | ``{"scenario": "lane-drop"}`` | 8 |
| ``on-ramp`` | ``icv_envs/highway_formation-v0`` | ``{"scenario": "on-ramp"}`` | 8 |
| ``intersection-1500`` | ``icv_envs/intersection-v0`` | 1500 veh/h, 120 s after an 80 s expert warm-up | 4 |
| ``highway-ramps`` | ``icv_envs/highway_ramps-v0`` | one on-ramp and one off-ramp, 3 km, 120 s | 2 |

Policies on each task: ``expert``, the env's reference methods (``idm``,
``lane-lp`` on the highway-ramps env; ``single-vp``, ``fcfs``, ``fcfs-tight`` at the
intersection), ``zero``, ``random``, and every saved model under
``--models`` (a directory holding ``model.zip`` + ``run.json``, from
``baselines/``) that was trained on the task: same env family and, for each
key of the task's config, the same value in the model's training config (a
``scenario`` also matches a model whose ``scenarios`` list holds it, e.g. a
behaviour clone of all five highway scenarios). A model's ``action`` config
(its ``--action-type``) is kept. Every policy drives every agent (the
PettingZoo env, :func:`icv_envs.rl.evaluate.evaluate`).

Seeds: episode ``k`` of every task resets with ``seed + k`` (default
1,000,000 + k). The training scripts never reach them: the PPO scripts train
on seeds ``seed + copy + n_copies * episode`` (below ~10^4 in any run this
package documents), ``bc_expert.py`` on ``seed * 10^5 + 10^4 * iteration + episode``
(seed 0: below 10^5), the recipe's validation on 90,000 + k.

Metrics per episode (each episode is one run in rliable's sense, the task
one stratum): ``return`` (summed reward of all agents), ``collisions_per_100``
(vehicles in a collision or that left the drivable surface, and at the
intersection also those that drove back out of their approach road, per 100
vehicles of the episode; the intersection counts the spawned vehicles; a
highway vehicle reaching the end of the road is a truncation, not a failure), ``mean_speed``
(m/s), ``speed_fluctuation`` (mean |dv/dt| of the realised speed, m/s^2), ``throughput``
(intersection: achieved veh/h cleared on their own movement; highway-ramps:
exited vehicles per hour; the highway-formation scenarios have no exit and no
throughput). For each metric: the mean and rliable's interquartile mean (IQM),
each with a 95% stratified-bootstrap percentile interval
(``rliable.library.get_interval_estimates``, ``--reps`` resamples, a fixed
random state, so the table is reproducible). Without rliable (or where it
cannot be imported) the same estimators run in numpy (IQM =
``scipy.stats.trim_mean(x, 0.25)``, percentile bootstrap over episodes);
``ci_backend`` in the CSV says which.

Writes into ``--out``: ``leaderboard.csv`` (one row per task x policy, every
estimate), ``leaderboard.md`` (the Markdown table), ``leaderboard.png``
(per task: learning curves of the ``baselines/ppo_recipe.py`` runs, the
validation return as a share of the expert's leaderboard return and the
collisions per 100 vehicles, with the targets 90% and 1 drawn; dashed, the
DAgger rounds of ``baselines/bc_expert.py`` runs: each learner rollout's
return per episode as a share of the expert's rollout of round 0 (each
round on its own training seeds); and each
policy's mean return, at the intersection its throughput, as a share of the
expert's with its interval, red where it has more than 1 collision per 100
vehicles), ``evals/<task>/<policy>.json``
(the full evaluation). ``--reuse`` keeps an ``evals`` file whose policy,
config, episodes and seed match (and, for a model, that is newer than its
``model.zip``).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from icv_envs.rl.envs import env_family, resolve_env
from icv_envs.rl.evaluate import evaluate, policy_names
from icv_envs.rl.models import ensemble_member_dirs

__all__ = ["TASKS", "Task", "METRICS", "run_leaderboard", "interval_estimates", "find_models", "model_fits",
           "episode_metrics", "main", "add_arguments"]

DEFAULT_SEED = 1_000_000
_RLIABLE_BROKEN = False  # set when rliable's bootstrap failed once (see interval_estimates)
METRICS = ("return", "collisions_per_100", "mean_speed", "speed_fluctuation", "throughput")


@dataclass(frozen=True)
class Task:
    name: str
    env: str
    config: dict = field(default_factory=dict)
    episodes: int = 4


TASKS = {t.name: t for t in (
    Task("lane-drop", "icv_envs/highway_formation-v0", {"scenario": "lane-drop"}, 8),
    Task("on-ramp", "icv_envs/highway_formation-v0", {"scenario": "on-ramp"}, 8),
    Task("intersection-1500", "icv_envs/intersection-v0", {"throughput": 1500, "duration": 120, "warmup": 80}, 4),
    Task("highway-ramps", "icv_envs/highway_ramps-v0",
         {"ramps": 1, "road_length": 3000.0, "seam": 500.0, "duration": 120.0}, 2),
)}


# ---------------------------------------------------------------- models
def model_fits(meta: dict, task: Task) -> bool:
    """Whether a model's ``run.json`` says it was trained on ``task``."""
    try:
        if env_family(meta.get("env", "")) != env_family(task.env):
            return False
    except ValueError:
        return False
    cfg = meta.get("config") or {}
    for k, v in task.config.items():
        if k == "scenario" and v in (meta.get("scenarios") or []):
            continue
        if cfg.get(k) != v:
            return False
    return True


def find_models(models_dir, task: Task) -> list[tuple[str, Path, dict]]:
    """``(label, directory, run.json)`` of every model under ``models_dir``
    trained on ``task``, sorted by label (``models_dir`` None: no models)."""
    found = []
    if models_dir is None:
        return found
    root = _check_models_dir(models_dir)
    for meta_path in sorted(root.glob("*/run.json")):
        meta = json.loads(meta_path.read_text())
        if not (meta_path.parent / "model.zip").is_file() and meta.get("algo") != "ensemble":
            continue
        if model_fits(meta, task):
            found.append((meta_path.parent.name, meta_path.parent, meta))
    return found


def _check_models_dir(models_dir) -> Path:
    """``models_dir`` as a Path; ``ValueError`` unless it is an existing directory."""
    if not isinstance(models_dir, (str, Path)) or not Path(models_dir).is_dir():
        raise ValueError(f"models_dir = {str(models_dir)!r} is not an existing directory; allowed: a directory of "
                         f"saved models (DIR/*/model.zip + run.json), or None in the Python API (no saved models)")
    return Path(models_dir)


# ---------------------------------------------------------------- metrics
def episode_metrics(row: dict, family: str) -> dict:
    """The leaderboard metrics of one episode row of :func:`evaluate`."""
    vehicles = row.get("spawned") if family == "intersection" else row.get("vehicles", row.get("spawned"))
    # ``left_road`` is a failure only at the intersection (driving back out of the approach road); on the
    # highway it is the end of the road, a truncation (the env's docs), and a fast policy reaches it:
    # counting it made ppo_meta_on-ramp_50min, collision-free, show 14.3 "collisions" per 100 vehicles
    failures = int(row.get("collisions", 0))
    if family == "intersection":
        failures += int(row.get("left_road", 0) or 0)
    thr = None
    if family == "intersection":
        thr = row.get("achieved_throughput")
    elif family == "highway_ramps" and row.get("sim_seconds"):
        thr = 3600.0 * row.get("exited", 0) / row["sim_seconds"]
    return {
        "return": float(row["episode_return"]),
        "collisions_per_100": 100.0 * failures / vehicles if vehicles else math.nan,
        "mean_speed": float(row["mean_speed"]) if row.get("mean_speed") is not None else math.nan,
        "speed_fluctuation": (float(row["speed_fluctuation"]) if row.get("speed_fluctuation") is not None
                              else math.nan),
        "throughput": float(thr) if thr is not None else math.nan,
    }


def _iqm(x: np.ndarray) -> float:
    from scipy.stats import trim_mean

    return float(trim_mean(x, proportiontocut=0.25, axis=None))


def _mark_rliable_broken() -> None:
    global _RLIABLE_BROKEN
    _RLIABLE_BROKEN = True


def interval_estimates(scores: np.ndarray, reps: int = 2000, seed: int = 0, backend: str = "auto") -> dict:
    """Mean and IQM of ``scores`` (one value per episode) with 95% percentile
    bootstrap intervals: ``{"mean", "mean_lo", "mean_hi", "iqm", "iqm_lo",
    "iqm_hi", "ci_backend"}``. ``backend``: ``"rliable"``, ``"numpy"`` or
    ``"auto"`` (rliable if it imports)."""
    x = np.asarray(scores, dtype=float).reshape(-1)
    if backend not in ("auto", "rliable", "numpy"):
        raise ValueError(f"backend {backend!r} is invalid; allowed: auto, rliable, numpy")
    if len(x) == 0 or not np.all(np.isfinite(x)):
        return {"mean": math.nan, "mean_lo": math.nan, "mean_hi": math.nan, "iqm": math.nan, "iqm_lo": math.nan,
                "iqm_hi": math.nan, "ci_backend": None}
    if backend != "numpy" and _RLIABLE_BROKEN and backend == "auto":
        backend = "numpy"  # a failed import is not cached by Python: do not retry it for every estimate
    if backend != "numpy":
        try:
            from rliable import library as rly
            from rliable import metrics as rlm

            func = lambda s: np.array([rlm.aggregate_mean(s), rlm.aggregate_iqm(s)])  # noqa: E731
            point, ci = rly.get_interval_estimates({"p": x[:, None]}, func, reps=reps,
                                                   random_state=np.random.RandomState(seed))
        except Exception:  # noqa: BLE001 - rliable missing, or broken by its arch pin (arch 7 vs pandas 3, arch 8)
            if backend == "rliable":
                raise
            _mark_rliable_broken()
        else:
            (m, q), ((mlo, qlo), (mhi, qhi)) = point["p"], ci["p"]
            return {"mean": float(m), "mean_lo": float(mlo), "mean_hi": float(mhi), "iqm": float(q),
                    "iqm_lo": float(qlo), "iqm_hi": float(qhi), "ci_backend": "rliable"}
    rng = np.random.RandomState(seed)
    idx = rng.randint(0, len(x), size=(reps, len(x)))
    boots = x[idx]
    bm = boots.mean(axis=1)
    from scipy.stats import trim_mean

    bq = trim_mean(boots, proportiontocut=0.25, axis=1)
    return {"mean": float(x.mean()), "mean_lo": float(np.percentile(bm, 2.5)), "mean_hi": float(np.percentile(bm, 97.5)),
            "iqm": _iqm(x), "iqm_lo": float(np.percentile(bq, 2.5)), "iqm_hi": float(np.percentile(bq, 97.5)),
            "ci_backend": "numpy"}


# ---------------------------------------------------------------- running
def _evaluate_cached(path: Path, task: Task, policy, config: dict, episodes: int, seed: int, reuse: bool,
                     model_zip: Path | None) -> dict:
    if reuse and path.is_file():
        old = json.loads(path.read_text())
        fresh = model_zip is None or path.stat().st_mtime > model_zip.stat().st_mtime
        old_cfg = dict(old.get("config") or {})
        if old.get("method") == policy:  # a reference method: evaluate() sets config["method"] to it
            old_cfg.pop("method", None)
        if (fresh and old.get("episodes") == episodes and old.get("seed") == seed and old_cfg == config
                and old.get("policy") == str(policy)):
            return old
    res = evaluate(task.env, policy, episodes=episodes, seed=seed, config=config)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(res, indent=2))
    return res


def _policies(task: Task, models_dir) -> list[tuple[str, object, dict, Path | None]]:
    """``(label, policy, config, model.zip)`` for every policy on ``task``."""
    names = policy_names(task.env)
    refs = [n for n in names if n not in ("expert", "zero", "random")]
    expert_method = {"highway_ramps": "formation", "intersection": "multi-vp"}.get(env_family(task.env))
    out = [("expert", "expert", dict(task.config), None)]
    out += [(r, r, dict(task.config), None) for r in refs if r != expert_method]
    out += [("zero", "zero", dict(task.config), None), ("random", "random", dict(task.config), None)]
    for label, d, meta in find_models(models_dir, task):
        cfg = dict(task.config)
        # evaluated through the interface it was trained on (action and
        # observation types); the task's config (traffic, reward) is the board's
        for key in ("action", "observation"):
            if key in (meta.get("config") or {}):
                cfg[key] = meta["config"][key]
        out.append((label, str(d), cfg, _newest_model_file(d, meta)))
    return out


def _newest_model_file(d: Path, meta: dict) -> Path:
    """The file whose age decides whether a cached evaluation is fresh: ``model.zip``, or for an ensemble
    (no model.zip) the newest of its ``run.json`` and its members' ``model.zip``."""
    if (d / "model.zip").is_file() or meta.get("algo") != "ensemble":
        return d / "model.zip"
    files = [d / "run.json"] + [m / "model.zip" for m in ensemble_member_dirs(d, meta) if (m / "model.zip").is_file()]
    return max(files, key=lambda f: f.stat().st_mtime)


def run_leaderboard(out="results/leaderboard", models_dir="results/learned", tasks=None, episodes=None,
                    seed: int = DEFAULT_SEED, reps: int = 2000, reuse: bool = False, progress: bool = True,
                    backend: str = "auto") -> list[dict]:
    """Evaluate, aggregate and write CSV + Markdown + PNG; returns the rows."""
    out = Path(out)
    if tasks is not None and not isinstance(tasks, (list, tuple)):
        raise ValueError(f"tasks = {tasks!r}; allowed: None (every task) or a list of task names of {', '.join(TASKS)}")
    names = list(TASKS) if tasks is None else list(tasks)
    if not names:
        raise ValueError(f"tasks = {tasks!r} is empty; allowed: None (every task) or a non-empty list of "
                         f"{', '.join(TASKS)}")
    bad = [t for t in names if not isinstance(t, str) or t not in TASKS]
    if bad:
        raise ValueError(f"unknown tasks {bad}; allowed: {', '.join(TASKS)}")
    dup = sorted({t for t in names if names.count(t) > 1})
    if dup:
        raise ValueError(f"tasks {dup} given more than once in {names}; allowed: each task once")
    if episodes is not None and (isinstance(episodes, bool) or int(episodes) != episodes or episodes < 1):
        raise ValueError(f"episodes = {episodes!r} is invalid; allowed: an integer >= 1 (or None: each task's own)")
    if isinstance(reps, bool) or not isinstance(reps, (int, np.integer)) or reps < 10:
        raise ValueError(f"reps = {reps!r} is invalid; allowed: an integer >= 10")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed = {seed!r} is invalid; allowed: an integer >= 0")
    if backend not in ("auto", "rliable", "numpy"):
        raise ValueError(f"backend {backend!r} is invalid; allowed: auto, rliable, numpy")
    if models_dir is not None:
        _check_models_dir(models_dir)
    jobs = [(TASKS[t], *p) for t in names for p in _policies(TASKS[t], models_dir)]
    try:
        from tqdm import tqdm

        bar = tqdm(jobs, desc="leaderboard", disable=not progress)
    except ImportError:  # pragma: no cover
        bar = jobs
    rows = []
    for task, label, policy, cfg, zip_path in bar:
        n = int(episodes) if episodes is not None else task.episodes
        t0 = time.perf_counter()
        res = _evaluate_cached(out / "evals" / task.name / f"{label}.json", task, policy, cfg, n, seed, reuse,
                               zip_path)
        fam = env_family(task.env)
        per = [episode_metrics(r, fam) for r in res["per_episode"]]
        row = {"task": task.name, "policy": label, "kind": _kind(label, res), "episodes": n, "seed": seed,
               "eval_seconds": round(time.perf_counter() - t0, 2)}
        for m in METRICS:
            est = interval_estimates([p[m] for p in per], reps=reps, seed=0, backend=backend)
            row["ci_backend"] = est.pop("ci_backend") or row.get("ci_backend")
            row.update({f"{m}_{k}": v for k, v in est.items()})
        rows.append(row)
    for task in names:  # return as a share of the expert's
        ex = next(r for r in rows if r["task"] == task and r["policy"] == "expert")
        for r in rows:
            if r["task"] == task:
                for m in ("return", "throughput"):
                    e = ex[f"{m}_mean"]
                    r[f"{m}_vs_expert"] = r[f"{m}_mean"] / e if e and math.isfinite(e) else math.nan
    out.mkdir(parents=True, exist_ok=True)
    _write_csv(out / "leaderboard.csv", rows)
    (out / "leaderboard.md").write_text(markdown(rows))
    plot(out / "leaderboard.png", rows, models_dir)
    return rows


def _kind(label: str, res: dict) -> str:
    if label in ("expert",):
        return "expert"
    if label in ("zero", "random"):
        return "trivial"
    if res.get("algo") == label:
        return "reference"
    return f"learned ({res.get('algo')})"


def _write_csv(path: Path, rows: list[dict]) -> None:
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow(r)


def _fmt(r: dict, m: str, stat: str = "mean", digits: int = 1) -> str:
    v, lo, hi = r[f"{m}_{stat}"], r[f"{m}_{stat}_lo"], r[f"{m}_{stat}_hi"]
    if v is None or not math.isfinite(v):
        return "-"
    return f"{v:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def _pct(v) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{100 * v:.0f}%"


def markdown(rows: list[dict]) -> str:
    """One table per task; cells: estimate [95% interval]."""
    lines = []
    for task in dict.fromkeys(r["task"] for r in rows):
        t = TASKS[task]
        rs = [r for r in rows if r["task"] == task]
        lines += [f"### {task}: `{t.env}` `{json.dumps(t.config)}`, {rs[0]['episodes']} episodes, "
                  f"seeds {rs[0]['seed']}..{rs[0]['seed'] + rs[0]['episodes'] - 1}", "",
                  "| policy | kind | return IQM | return mean | return vs expert | collisions / 100 veh | mean speed (m/s) "
                  "| speed fluct. (m/s^2) | throughput (veh/h) | throughput vs expert |",
                  "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for r in rs:
            lines.append(f"| {r['policy']} | {r['kind']} | {_fmt(r, 'return', 'iqm', 0)} | {_fmt(r, 'return', 'mean', 0)} "
                         f"| {_pct(r['return_vs_expert'])} | {_fmt(r, 'collisions_per_100')} "
                         f"| {_fmt(r, 'mean_speed', digits=2)} | {_fmt(r, 'speed_fluctuation', digits=3)} "
                         f"| {_fmt(r, 'throughput', digits=0)} | {_pct(r['throughput_vs_expert'])} |")
        lines.append("")
    return "\n".join(lines)


def _curves(models_dir) -> tuple[dict, dict]:
    """Learning curves per task, from one pass over the models: ``curve.csv``
    of ``baselines/ppo_recipe.py`` runs, and the DAgger rounds of
    ``baselines/bc_expert.py`` runs (after each round's env steps,
    cumulative, the return per episode of the learner's rollout as a share
    of the expert's rollout of round 0). Every DAgger round has its own
    training seeds: on the highway scenarios the return hardly depends on
    the seed, at the intersection it moves with the arrivals (a noisy curve,
    shares above 1 are seeds with more traffic)."""
    ppo: dict[str, list] = {}
    dagger: dict[str, list] = {}
    for task in TASKS.values():
        for label, d, meta in find_models(models_dir, task):
            p = d / "curve.csv"
            if p.is_file():
                with open(p) as f:
                    rows = [r for r in csv.DictReader(f) if r.get("val_return")]
                ppo.setdefault(task.name, []).append((label, rows))
            rounds = (meta.get("train") or {}).get("rounds") or []
            if meta.get("algo") != "bc_expert" or len(rounds) < 2 or rounds[0].get("driver") != "expert":
                continue
            r0 = rounds[0]["rollout"]["return_per_episode"]
            if not r0:
                continue
            steps = np.cumsum([r["rollout"]["env_steps"] for r in rounds])
            x = [float(s) for s in steps[1:]]
            y = [r["rollout"]["return_per_episode"] / r0 for r in rounds[1:]]
            dagger.setdefault(task.name, []).append((label, x, y))
    return ppo, dagger


def plot(path: Path, rows: list[dict], models_dir) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tasks = list(dict.fromkeys(r["task"] for r in rows))
    curves, dagger = _curves(models_dir)
    fig, axes = plt.subplots(3, len(tasks), figsize=(4.6 * len(tasks), 10), squeeze=False)
    for j, task in enumerate(tasks):
        rs = [r for r in rows if r["task"] == task]
        ex = next(r for r in rs if r["policy"] == "expert")["return_mean"] or math.nan
        a0, a1, a2 = axes[:, j]
        for label, cr in curves.get(task, []):
            x = [float(c["env_steps"]) for c in cr]
            a0.plot(x, [float(c["val_return"]) / ex for c in cr], "o-", ms=3, label=label)
            a1.plot(x, [float(c["val_collisions_per_100"]) for c in cr], "o-", ms=3, label=label)
        for label, x, y in dagger.get(task, []):
            a0.plot(x, y, "s--", ms=3, label=f"{label} (DAgger rollouts / expert's)")
        a0.axhline(0.9, color="k", ls="--", lw=0.8)
        a1.axhline(1.0, color="k", ls="--", lw=0.8)
        a0.set(title=f"{task}: learning curves", xlabel="env steps", ylabel="validation return / expert")
        a1.set(xlabel="env steps", ylabel="validation collisions / 100 veh")
        if curves.get(task) or dagger.get(task):
            a0.legend(fontsize=7)
        else:
            a0.text(0.5, 0.5, "no recipe run", ha="center", transform=a0.transAxes)
        # the bar: the target's measure, throughput at the intersection (returns are not comparable across
        # its methods), the return elsewhere; as a share of the expert's, with the 95% interval
        key = "throughput" if env_family(TASKS[task].env) == "intersection" else "return"
        ref = next(r for r in rs if r["policy"] == "expert")[f"{key}_mean"]
        ref = ref if ref and math.isfinite(ref) else math.nan  # an expert with no throughput (a tiny run): no share
        y = np.arange(len(rs))
        v = np.array([r[f"{key}_mean"] / ref for r in rs])
        err = np.array([[r[f"{key}_mean"] - r[f"{key}_mean_lo"], r[f"{key}_mean_hi"] - r[f"{key}_mean"]]
                        for r in rs]).T
        colors = ["C3" if r["collisions_per_100_mean"] > 1.0 else "C2" for r in rs]
        a2.barh(y, v, xerr=err / ref, color=colors, alpha=0.8)
        a2.axvline(0.9, color="k", ls="--", lw=0.8)
        a2.set_yticks(y, [r["policy"] for r in rs], fontsize=7)
        a2.invert_yaxis()
        a2.set(xlabel=f"mean {key} / expert's (green: <= 1 collision / 100 veh)")
        for a in (a0, a1, a2):
            a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


# ---------------------------------------------------------------- CLI
def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    p.add_argument("--out", default="results/leaderboard", help="output directory (leaderboard.csv/.md/.png, evals/)")
    p.add_argument("--models", default=None,
                   help="directory of saved models (DIR/*/model.zip); 'none': the built-in policies only "
                        "(default: results/learned when it exists, else none)")
    p.add_argument("--tasks", default=None, help=f"comma-separated subset of {', '.join(TASKS)}")
    p.add_argument("--episodes", type=int, default=None, help="episodes per policy (default: each task's own)")
    p.add_argument("--seed", type=int, default=DEFAULT_SEED, help="episode k resets with seed + k")
    p.add_argument("--reps", type=int, default=2000, help="bootstrap resamples")
    p.add_argument("--reuse", action="store_true", help="reuse matching evals/*.json")
    return p


def run(args) -> int:
    tasks = None if args.tasks is None else [t.strip() for t in args.tasks.split(",") if t.strip()]
    # a given directory must exist (a typo evaluated the built-in policies only, silently, until stop 45);
    # not given: the repository's results/learned when run from a checkout, else no saved models
    models = args.models
    if models is None:
        models = "results/learned" if Path("results/learned").is_dir() else None
    elif models.lower() == "none":
        models = None
    try:
        rows = run_leaderboard(args.out, models, tasks, args.episodes, args.seed, args.reps, args.reuse)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(markdown(rows))
    return 0


def main(argv=None) -> int:
    p = add_arguments(argparse.ArgumentParser(prog="icv-envs leaderboard", description=__doc__,
                                              formatter_class=argparse.RawDescriptionHelpFormatter))
    return run(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
