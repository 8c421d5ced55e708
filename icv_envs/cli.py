"""``icv-envs`` command line.

    icv-envs demo [--out DIR] [--seed S] [--no-video]
    icv-envs run highway-formation --scenario lane-drop --policy expert --seconds 60 --seed 0 --out DIR [--video]
    icv-envs run highway-ramps --method formation --vgr 0.333 --seconds 600 --seed 0 --out DIR
    icv-envs run intersection --method multi-vp --throughput 1500 --lane-use paper --seconds 120 --seed 0 --out DIR [--video]
    icv-envs compare highway-ramps --methods formation,lane-lp,idm --vgr 0.1,0.2,0.33,0.5 --seeds 3 --seconds 600 --out DIR
    icv-envs bench highway-formation [--sizes 50,200,800] [--seconds 10] [--stock-seconds 1]
    icv-envs bench highway-ramps [--seconds 600] [--vgr 0.333] [--vs-sumo [--api dicts|lean|rows]]
    icv-envs compare intersection --methods multi-vp,single-vp,fcfs,fcfs-tight --throughput 500,1000,1500,2000 --seeds 3|5,7,10-12 --seconds 600 --out DIR [--lane-use paper|exclusive] [--warmup 100] [--backend ray]
    icv-envs bench intersection [--seconds 500] [--warmup 100] [--seeds 3] [--throughput 2200] [--method multi-vp] [--api dicts|lean|rows]
    icv-envs conflicts --lane-use paper|exclusive [--json]
    icv-envs bench train
    icv-envs leaderboard [--out DIR] [--models DIR] [--tasks T,...] [--episodes N] [--reuse]
    icv-envs evaluate --env ID --policy expert|idm|lane-lp|single-vp|fcfs|zero|random|PATH --episodes N --seed S [--out DIR]
    icv-envs list [--json]
    icv-envs --version

Every command prints one JSON line last, on stdout (metrics or benchmark
results). Progress bars go to stderr and are shown only when stderr is a
terminal, so redirected output holds result lines only. Bad arguments exit
with status 2 and a message naming the value and what is allowed.
Documentation: docs/index.md (``mkdocs serve`` in the repository).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from icv_envs import __version__
from icv_envs._cli_args import (_HelpFormatter, _choice, _floats, _names, _nonneg_int, _positive_float, _positive_int,
                                _seed_list, _sizes)
from icv_envs.envs.highway_ramps import METHODS as RAMP_METHODS
from icv_envs.envs.intersection import METHODS as INTERSECTION_METHODS
from icv_envs.envs.scenarios import SCENARIOS
from icv_envs.experiments.bench import APIS
from icv_envs.platoon.geometry import LANE_USE_PRESETS
from icv_envs.policies import POLICIES

ENVS = ("highway-formation", "highway-ramps", "intersection")
#: what each ``--method`` means, per env (``icv-envs list``)
METHODS = {"highway-ramps": tuple(RAMP_METHODS), "intersection": tuple(INTERSECTION_METHODS)}
DEFAULT_METHOD = {"highway-ramps": "formation", "intersection": "multi-vp"}
LANE_USES = tuple(LANE_USE_PRESETS)
BACKENDS = ("process", "ray")
SCENARIO_HELP = {
    "free": "no event: formations drive on a straight 4-lane road",
    "lane-drop": "Fig. 7a: 4 lanes become 3 at 700 m; the formation re-forms on 3 lanes",
    "lane-change": "Fig. 7b: an obstacle blocks lane 2 at 900 m; lane changes inside the formation",
    "off-ramp": "Fig. 7c: a member leaves the formation at the off-ramp at 900 m",
    "on-ramp": "Fig. 7d: a vehicle joins from the on-ramp (merge 650-750 m)",
}
METHOD_HELP = {
    "formation": "interlaced formations on the left three lanes, the formation expert drives (paper Sec. 3)",
    "lane-lp": "optimal lane assignment LP at the ramps (Dao et al. 2007), IDM/MOBIL drive",
    "idm": "IDM car following and MOBIL lane changes, no coordination",
    "lane-lp-close": "lane-lp at the formation members' 0.5 s IDM time gap (equal margins)",
    "idm-close": "idm at the formation members' 0.5 s IDM time gap (equal margins)",
    "multi-vp": "regrouping + improved virtual platoon, a node per sub-formation (paper Sec. 4-5)",
    "single-vp": "virtual platoon with one vehicle per node",
    "fcfs": "tile reservation, first come first served (Dresner & Stone's AIM)",
    "fcfs-tight": "tile reservation with 0.2 s / 0.5 m buffers",
}
POLICY_HELP = {
    "expert": "the env's scripted expert (infos[agent]['expert_action'], in the env's action type)",
    "zero": "coast straight: action [0, 0] (DiscreteMetaAction: IDLE)",
    "random": "uniform random actions over the action space (seeded)",
}


def _progress() -> bool:
    """Show progress bars only on a terminal (they go to stderr)."""
    return sys.stderr.isatty()
BENCHES = ("highway-formation", "highway-ramps", "train", "intersection")
API_CHOICES = tuple(APIS)  # bench highway-ramps --vs-sumo --api, bench intersection --api
COMPARES = ("highway-ramps", "intersection")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="icv-envs", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"icv-envs {__version__}",
                   help="print the package version and exit")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    fmt = _HelpFormatter

    d = sub.add_parser("demo", help="run the four Fig. 7 scenarios with the expert; metrics + GIFs", formatter_class=fmt)
    d.add_argument("--out", default="demo_out", help="output directory")
    d.add_argument("--seed", type=_nonneg_int("--seed"), default=0, help="episode seed")
    d.add_argument("--seconds", type=_positive_float("--seconds"), default=60.0, help="simulated seconds per scenario")
    d.add_argument("--no-video", action="store_true", help="skip the GIFs")

    r = sub.add_parser("run", help="run one episode and print its metrics", formatter_class=fmt)
    r.add_argument("env", type=_choice("env", ENVS), metavar="ENV", help=f"one of: {', '.join(ENVS)}")
    r.add_argument("--scenario", type=_choice("scenario", sorted(SCENARIOS)), default=None,
                   help=f"highway-formation (default lane-drop): {', '.join(sorted(SCENARIOS))}")
    r.add_argument("--policy", type=_choice("policy", POLICIES), default=None,
                   help=f"highway-formation (default expert): who drives every vehicle, {', '.join(POLICIES)}")
    r.add_argument("--seconds", type=_positive_float("--seconds"), default=60.0, help="simulated seconds")
    r.add_argument("--seed", type=_nonneg_int("--seed"), default=0, help="episode seed")
    r.add_argument("--out", default=None, help="directory for metrics.json (and video.gif)")
    r.add_argument("--video", action="store_true", help="highway-formation, intersection: also write video.gif to --out")
    r.add_argument("--config", default=None, help="JSON object of extra env config keys (see docs/envs/)")
    r.add_argument("--method", default=None,  # checked per env by validate_grid (exit 2)
                   help="highway-ramps: " + ", ".join(METHODS["highway-ramps"]) + " (default formation); "
                   "intersection: " + ", ".join(METHODS["intersection"]) + " (default multi-vp)")
    r.add_argument("--vgr", type=float, default=None,  # range checked by validate_grid (exit 2)
                   help="highway-ramps: vehicles/s per on-ramp, in (0, 1] (default 1/3)")
    r.add_argument("--throughput", type=float, default=None,  # range checked by validate_grid (exit 2)
                   help="intersection: vehicles/h entering the intersection, all legs (default 1500)")
    r.add_argument("--lane-use", dest="lane_use", type=_choice("lane use", LANE_USES), default=None,
                   help=f"intersection: lane-use table, {', '.join(LANE_USES)} (default paper)")

    c = sub.add_parser("compare", help="methods x parameters x seeds sweep, in parallel, CSV + plots", formatter_class=fmt)
    c.add_argument("target", type=_choice("comparison", COMPARES), metavar="TARGET", help=f"one of: {', '.join(COMPARES)}")
    c.add_argument("--methods", type=_names, default=None,
                   help="comma-separated; highway-ramps: " + ",".join(METHODS["highway-ramps"])
                   + "; intersection: " + ",".join(METHODS["intersection"])
                   + " (default: highway-ramps formation,lane-lp,idm; intersection all but fcfs-tight)")
    c.add_argument("--throughput", default=None,
                   help="intersection: vehicles/h entering the intersection, comma-separated (default 1000,1500,2000,2500,3000)")
    c.add_argument("--lane-use", dest="lane_use", default=None,  # checked by the env config (exit 2)
                   help=f"intersection: {', '.join(LANE_USES)} (default paper)")
    c.add_argument("--vgr", type=_floats("--vgr"), default=None,
                   help="highway-ramps: vehicles/s per on-ramp, comma-separated (default 0.1,0.2,0.33,0.5)")
    c.add_argument("--warmup", type=float, default=None,
                   help="intersection: seconds run before the statistics start (default 100)")
    c.add_argument("--seeds", type=_seed_list, default=[0, 1, 2],
                   help="a count N (seeds 0..N-1) or a list/range such as 5,7,10-12")
    c.add_argument("--seconds", type=float, default=600.0, help="simulated seconds per run")
    c.add_argument("--out", default="compare_out", help="output directory (CSV, JSON, plots)")
    c.add_argument("--backend", type=_choice("backend", BACKENDS), default="process",
                   help="process (local pool) or ray")
    c.add_argument("--workers", type=_positive_int("--workers"), default=None,
                   help="local pool size (--backend process; default: all cores)")

    b = sub.add_parser("bench", help="speed benchmarks (ratios against a reference measured in the same run)",
                       formatter_class=fmt)
    b.add_argument("target", type=_choice("benchmark", BENCHES), metavar="TARGET", help=f"one of: {', '.join(BENCHES)}")
    b.add_argument("--sizes", type=_sizes, default=None,
                   help="highway-formation: vehicle counts, comma-separated (default 50,200,800)")
    b.add_argument("--seconds", type=_positive_float("--seconds"), default=None,
                   help="simulated seconds (highway-formation: per size, default 10; highway-ramps: default 600; "
                        "intersection: timed per seed, default 500)")
    b.add_argument("--stock-seconds", type=_positive_float("--stock-seconds"), default=None,
                   help="highway-formation: simulated seconds of highway-v0 per size (it is slow; default 1)")
    b.add_argument("--vgr", type=float, default=None, help="highway-ramps: vehicles/s per on-ramp (default 1/3)")
    b.add_argument("--throughput", type=float, default=None,
                   help="intersection: vehicles/h (default 2200: about 30-85 vehicles in the zones, 50 on average)")
    b.add_argument("--warmup", type=_positive_float("--warmup", allow_zero=True), default=None,
                   help="intersection: simulated seconds before the timing starts, per seed (default 100)")
    b.add_argument("--seeds", type=_positive_int("--seeds"), default=None,
                   help="intersection: number of seeds, 0 .. N-1 (default 3)")
    b.add_argument("--method", type=_choice("method", METHODS["intersection"]), default=None,
                   help="intersection: " + ", ".join(METHODS["intersection"]) + " (default multi-vp)")
    b.add_argument("--vs-sumo", dest="vs_sumo", action="store_true",
                   help="highway-ramps: time the last 100 s beside SUMO on the same ring, alternately (extra 'bench')")
    b.add_argument("--api", type=_choice("api", API_CHOICES), default=None,
                   help="highway-ramps --vs-sumo and intersection: how the agents are stepped: dicts (PettingZoo, "
                        "full infos; default), lean (PettingZoo, info_keys=[], expert_in_info=False) or rows "
                        "(step_rows: arrays)")
    b.add_argument("--out", default=None, help="also write the JSON to DIR/bench.json")

    from icv_envs.rl.evaluate import add_arguments as _eval_args

    _eval_args(sub.add_parser("evaluate", help="evaluate expert/zero/random or a model saved by baselines/",
                              formatter_class=fmt))
    from icv_envs.rl.leaderboard import add_arguments as _board_args

    _board_args(sub.add_parser("leaderboard", help="every policy on every task, held-out seeds, IQM + bootstrap CIs",
                               formatter_class=fmt))
    k = sub.add_parser("conflicts", help="conflict matrix of the 12 intersection movements (derived from the lane use)",
                       formatter_class=fmt)
    k.add_argument("--lane-use", dest="lane_use", default="paper",  # checked by conflicts_report (exit 2)
                   help=f"lane-use table, {', '.join(LANE_USES)}")
    k.add_argument("--json", action="store_true", help="print only the JSON report")
    ls = sub.add_parser("list", help="list environments, scenarios, methods and policies", formatter_class=fmt)
    ls.add_argument("--json", action="store_true", help="print only the JSON line")
    ds = sub.add_parser("dataset", help="record the expert as a Minari dataset (see icv_envs.rl.dataset)", formatter_class=fmt)
    ds.add_argument("--env", required=True, help="Gymnasium id (the ego) or PettingZoo id (one episode per vehicle)")
    ds.add_argument("--episodes", type=int, required=True, help="env episodes (seeds SEED, SEED+1, ...)")
    ds.add_argument("--out", required=True, help="directory of the Minari datasets (MINARI_DATASETS_PATH)")
    ds.add_argument("--seed", type=_nonneg_int("--seed"), default=0, help="seed of the first episode")
    ds.add_argument("--config", default=None, help="JSON dict of env config (or a .json file)")
    ds.add_argument("--dataset-id", dest="dataset_id", default=None, help="default: icv_envs/<family>/expert-v0")
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return _dispatch(args)
    except ValueError as exc:
        print(f"icv-envs: error: {exc}", file=sys.stderr)
        return 2


#: ``run`` options that apply to one env only: given for another, they are an error
_RUN_ONLY = {"--scenario": ("scenario", ("highway-formation",)), "--policy": ("policy", ("highway-formation",)),
             "--method": ("method", ("highway-ramps", "intersection")), "--vgr": ("vgr", ("highway-ramps",)),
             "--throughput": ("throughput", ("intersection",)), "--lane-use": ("lane_use", ("intersection",)),
             "--video": ("video", ("highway-formation", "intersection"))}


#: ``compare`` options that apply to one target only: given for another, they are an error
_COMPARE_ONLY = {"--vgr": ("vgr", ("highway-ramps",)), "--throughput": ("throughput", ("intersection",)),
                 "--lane-use": ("lane_use", ("intersection",)), "--warmup": ("warmup", ("intersection",))}


#: ``bench`` options that apply to some targets only: given for another, they are an error
_BENCH_ONLY = {"--sizes": ("sizes", ("highway-formation",)), "--stock-seconds": ("stock_seconds", ("highway-formation",)),
               "--seconds": ("seconds", ("highway-formation", "highway-ramps", "intersection")),
               "--vgr": ("vgr", ("highway-ramps",)), "--throughput": ("throughput", ("intersection",)),
               "--method": ("method", ("intersection",)), "--warmup": ("warmup", ("intersection",)),
               "--seeds": ("seeds", ("intersection",))}


def _reject_foreign_options(args, command: str, chosen: str, table: dict) -> None:
    """An option of ``table`` (:data:`_RUN_ONLY`, :data:`_COMPARE_ONLY`, :data:`_BENCH_ONLY`) given
    for a ``command`` target it does not belong to is an error naming the
    option and the targets it belongs to (an option not given is None, a
    flag not given False; a given 0 counts)."""
    for flag, (attr, owners) in table.items():
        v = getattr(args, attr, None)
        if v is not None and v is not False and chosen not in owners:
            raise ValueError(f"{flag} {v!r} does not apply to {command} {chosen}: it is an option of {command} "
                             + f" / {command} ".join(owners))


def _dispatch(args) -> int:
    if args.command == "evaluate":
        from icv_envs.rl.evaluate import run

        return run(args)
    if args.command == "leaderboard":
        from icv_envs.rl.leaderboard import run as run_board

        return run_board(args)
    if args.command == "dataset":
        from icv_envs.rl.dataset import record_expert_dataset
        from icv_envs.rl.envs import parse_config

        res = record_expert_dataset(args.env, args.episodes, args.out, seed=args.seed,
                                    config=parse_config(args.config), dataset_id=args.dataset_id,
                                    progress=sys.stderr.isatty())
        print(json.dumps(res))
        return 0
    if args.command == "list":
        return _list(args.json)
    if args.command == "run":
        _reject_foreign_options(args, "run", args.env, _RUN_ONLY)
    if args.command == "run" and args.env == "intersection":
        return _run_intersection(args)
    if args.command == "run" and args.env == "highway-ramps":
        from icv_envs.experiments.compare import run_ramps, validate_grid

        args.method = args.method or DEFAULT_METHOD["highway-ramps"]
        args.vgr = 1.0 / 3.0 if args.vgr is None else args.vgr
        validate_grid([args.method], [args.vgr], 1, args.seconds)
        m = run_ramps(args.method, args.vgr, args.seed, args.seconds, _json_config(args.config) or None)
        if args.out:
            Path(args.out).mkdir(parents=True, exist_ok=True)
            (Path(args.out) / "metrics.json").write_text(json.dumps(m))
        for k in ("timeseries", "heatmap_mean", "heatmap_final"):
            m.pop(k, None)
        print(json.dumps(m))
        return 0
    if args.command == "conflicts":
        from icv_envs.platoon import conflict_model, conflicts_report, format_matrix

        report = conflicts_report(args.lane_use)  # ValueError (exit 2) for an unknown lane use
        if not args.json:
            print(format_matrix(conflict_model(args.lane_use)))
        print(json.dumps(report))
        return 0
    if args.command == "compare":
        _reject_foreign_options(args, "compare", args.target, _COMPARE_ONLY)
        from icv_envs.experiments._checks import check_workers

        check_workers(args.workers, args.backend)
    if args.command == "compare" and args.target == "intersection":
        from icv_envs.experiments.intersection_compare import run_cli as compare_intersection_cli

        args.progress = _progress()
        summary = compare_intersection_cli(args, echo=lambda s: print(s, flush=True))
        print(json.dumps(summary))
        return 0
    if args.command == "compare":
        from icv_envs.experiments.compare import compare_highway_ramps

        args.methods = args.methods or ["formation", "lane-lp", "idm"]
        args.vgr = [0.1, 0.2, 0.33, 0.5] if args.vgr is None else args.vgr

        summary = compare_highway_ramps(args.methods, args.vgr, args.seeds, args.seconds, args.out,
                                        backend=args.backend, workers=args.workers, progress=_progress())
        for row in summary["table"]:
            print(f"{row['method']:10s} vgr={row['vgr']:<5g} remaining={row['remaining']:7.1f} "
                  f"mean_speed={row['mean_speed']:6.2f} speed_fluctuation={row['speed_fluctuation']:.3f} "
                  f"collisions={row['collisions']} lost={row['lost']}", flush=True)
        summary["out"] = args.out
        print(json.dumps(summary))
        return 0
    if args.command == "run":
        from icv_envs.experiments.run import run_highway_formation

        config = _json_config(args.config) or None
        if args.video and not args.out:
            raise ValueError("--video needs --out DIR to write the video to")
        m = run_highway_formation(args.scenario or "lane-drop", args.policy or "expert", args.seconds, args.seed, args.out, args.video,
                                  config, progress=_progress())
        print(json.dumps(m))
        return 0
    if args.command == "demo":
        from tqdm import tqdm

        from icv_envs.experiments.run import run_highway_formation

        out = Path(args.out)
        results = {}
        for scen in tqdm(["lane-drop", "lane-change", "off-ramp", "on-ramp"], desc="scenarios",
                         disable=not _progress()):
            m = run_highway_formation(scen, "expert", args.seconds, args.seed, out / scen, not args.no_video)
            results[scen] = m
            tqdm.write(  # stdout; the bar is on stderr (and only on a terminal)
                f"{scen:12s} collisions={m['collisions']} mean_speed={m['mean_speed']:.2f} m/s "
                f"speed_fluctuation={m['speed_fluctuation']:.3f} m/s^2 min_gap={m['min_gap']:.1f} m "
                f"formation_error_x={m['formation_error_x']:.2f} m off_target_lane={m['off_target_lane']}"
                + (f" video={m['video']}" if "video" in m else "")
            )
        summary = {"demo": "highway-formation", "out": str(out), "scenarios": results}
        (out / "summary.json").write_text(json.dumps(summary, indent=2))
        print(json.dumps(summary))
        return 0
    if args.command == "bench":
        from icv_envs.experiments.bench import bench_highway_formation, bench_highway_ramps

        _reject_foreign_options(args, "bench", args.target, _BENCH_ONLY)
        if args.vs_sumo and args.target != "highway-ramps":
            raise ValueError(f"--vs-sumo is an option of 'bench highway-ramps', not of 'bench {args.target}'")
        if args.api is not None and not (args.vs_sumo or args.target == "intersection"):
            raise ValueError(f"--api {args.api} is an option of 'bench highway-ramps --vs-sumo' and 'bench intersection'")
        if args.target == "intersection":
            from icv_envs.experiments.intersection_bench import run_cli as bench_intersection_cli

            res = bench_intersection_cli(args, echo=lambda s: print(s, flush=True))
        elif args.target == "train":
            from icv_envs.rl.bench import bench_train

            res = bench_train(echo=lambda s: print(s, flush=True))
        elif args.target == "highway-ramps":
            args.vgr = 1.0 / 3.0 if args.vgr is None else args.vgr
            if not 0 < args.vgr <= 1.0:
                raise ValueError(f"--vgr {args.vgr!r}; allowed: 0 < vgr <= 1")
            if args.vs_sumo:
                from icv_envs.experiments.sumo_bench import ramps_vs_sumo

                res = ramps_vs_sumo(args.seconds or 600.0, vgr=args.vgr, api=args.api or "dicts",
                                    echo=lambda s: print(s, flush=True))
            else:
                res = bench_highway_ramps(args.seconds or 600.0, args.vgr, echo=lambda s: print(s, flush=True))
        else:
            res = bench_highway_formation(args.sizes or [50, 200, 800], args.seconds or 10.0, args.stock_seconds or 1.0,
                                          echo=lambda s: print(s, flush=True))
        if args.out:
            Path(args.out).mkdir(parents=True, exist_ok=True)
            (Path(args.out) / "bench.json").write_text(json.dumps(res, indent=2))
        print(json.dumps(res))
        return 0
    raise ValueError(f"unknown command {args.command!r}")  # pragma: no cover


def _list(json_only: bool) -> int:
    """``icv-envs list``: every env id, scenario, method and policy."""
    import icv_envs
    from icv_envs.rl.evaluate import NAMED_POLICIES, REFERENCE_POLICIES

    out = {
        "gymnasium": sorted(icv_envs.GYM_IDS),
        "pettingzoo": sorted(icv_envs.PETTINGZOO_IDS),
        "cli_envs": list(ENVS),
        "scenarios": sorted(SCENARIOS),
        "methods": {env: list(ms) for env, ms in METHODS.items()},
        "policies": list(POLICIES),
        "evaluate_policies": {fam: list(NAMED_POLICIES) + list(refs) + ["PATH"]
                              for fam, refs in REFERENCE_POLICIES.items()},
        "lane_uses": list(LANE_USES),
    }
    if not json_only:
        lines = ["Gymnasium ids (one learned ego among experts):"]
        lines += [f"  {g}" for g in out["gymnasium"]]
        lines += ["PettingZoo ids (every vehicle an agent; pettingzoo.make('parallel', ID)):"]
        lines += [f"  {z}  (module icv_envs.{icv_envs.PETTINGZOO_IDS[z].rsplit('.', 1)[1]})" for z in out["pettingzoo"]]
        lines += ["Scenarios (icv-envs run highway-formation --scenario NAME):"]
        lines += [f"  {n:12s} {SCENARIO_HELP.get(n, '')}" for n in out["scenarios"]]
        for env, ms in METHODS.items():
            lines += [f"Methods of {env} (icv-envs run {env} --method NAME):"]
            lines += [f"  {m:12s} {METHOD_HELP.get(m, '')}" for m in ms]
        lines += ["Policies (icv-envs run highway-formation --policy NAME):"]
        lines += [f"  {n:12s} {POLICY_HELP.get(n, '')}" for n in out["policies"]]
        lines += ["Policies of icv-envs evaluate (per env family; PATH = a model saved by baselines/):"]
        lines += [f"  {fam:18s} {', '.join(ps)}" for fam, ps in out["evaluate_policies"].items()]
        lines += [f"Lane uses (intersection --lane-use): {', '.join(out['lane_uses'])}"]
        print("\n".join(lines))
    print(json.dumps(out))
    return 0


def _run_intersection(args) -> int:
    """``icv-envs run intersection``: one episode driven by the method's
    expert; prints the metrics (and writes metrics.json / video.gif to --out)."""
    import time

    from icv_envs.experiments._checks import check_run_config
    from icv_envs.experiments.intersection_compare import OWNED_CONFIG, validate_grid
    from icv_envs.envs.intersection_v0 import parallel_env

    method = args.method or DEFAULT_METHOD["intersection"]
    args.throughput = 1500.0 if args.throughput is None else args.throughput
    args.lane_use = args.lane_use or "paper"
    validate_grid([method], [args.throughput], 1, args.seconds)
    if args.video and not args.out:
        raise ValueError("--video needs --out DIR to write the video to")
    cfg = {"expert_in_info": False}
    cfg.update(check_run_config(_json_config(args.config), dict(OWNED_CONFIG, lane_use="--lane-use")))
    cfg.update({"method": method, "throughput": float(args.throughput), "duration": float(args.seconds),
                "lane_use": args.lane_use})
    env = parallel_env(render_mode="rgb_array" if args.video else None, **cfg)
    env.reset(seed=int(args.seed))
    frames = [env.render()] if args.video else []
    from tqdm import tqdm

    n_steps = int(round(args.seconds * env.core.config["policy_frequency"]))
    bar = tqdm(total=n_steps, desc=f"intersection/{method}", leave=False, disable=not _progress())
    t0 = time.perf_counter()
    while not env.episode_over:
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
        bar.update(1)
        if args.video:
            frames.append(env.render())
    bar.close()
    wall = time.perf_counter() - t0
    m = env.metrics()
    m.update({"env": "intersection", "method": method, "throughput": float(args.throughput), "seed": int(args.seed),
              "seconds": float(args.seconds), "lane_use": args.lane_use, "wall_seconds": wall})
    fps = 2 * env.core.config["policy_frequency"]  # twice real time
    env.close()
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        if frames:
            import imageio.v2 as imageio

            imageio.mimsave(out / "video.gif", frames, duration=1000.0 / fps, loop=0)
            m["video"] = str(out / "video.gif")
        (out / "metrics.json").write_text(json.dumps(m, indent=2))
    print(json.dumps(m))
    return 0


def _json_config(text) -> dict:
    """``--config`` parsed: a JSON object, else ValueError naming it."""
    if not text:
        return {}
    try:
        config = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"--config is not valid JSON: {exc}") from None
    if not isinstance(config, dict):
        raise ValueError(f"--config must be a JSON object, got {text!r}")
    return config


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
