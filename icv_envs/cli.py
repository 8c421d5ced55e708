"""``icv-envs`` command line.

    icv-envs demo [--out DIR] [--seed S] [--no-video]
    icv-envs run highway-formation --scenario lane-drop --policy expert --seconds 60 --seed 0 --out DIR [--video]
    icv-envs run highway-ramps --method formation --vgr 0.333 --seconds 600 --seed 0 --out DIR
    icv-envs compare highway-ramps --methods formation,lane-lp,idm --vgr 0.1,0.2,0.33,0.5 --seeds 3 --seconds 600 --out DIR
    icv-envs bench highway-formation [--sizes 50,200,800] [--seconds 10] [--stock-seconds 1]
    icv-envs bench highway-ramps [--seconds 600] [--vgr 0.333] [--vs-sumo]
    icv-envs compare intersection --methods multi-vp,single-vp,fcfs --throughput 1000,1500,2000,2500,3000 --seeds 3 --seconds 600 --out DIR [--lane-use paper|exclusive] [--backend ray]
    icv-envs bench intersection [--seconds 60] [--throughput 2200] [--method multi-vp]
    icv-envs conflicts --lane-use paper|exclusive [--json]
    icv-envs bench train
    icv-envs evaluate --env ID --policy expert|idm|lane-lp|single-vp|fcfs|zero|random|PATH --episodes N --seed S [--out DIR]
    icv-envs list

Every command prints one JSON line last (metrics or benchmark results).
Bad arguments exit with status 2 and a message naming the value and what is
allowed.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from icv_envs.envs.scenarios import SCENARIOS
from icv_envs.policies import POLICIES

ENVS = ("highway-formation", "highway-ramps")
BENCHES = ("highway-formation", "highway-ramps", "train", "intersection")
COMPARES = ("highway-ramps", "intersection")


def _positive_float(name):
    def parse(text):
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number > 0, got {text!r}") from None
        if not v > 0 or v != v or v == float("inf"):
            raise argparse.ArgumentTypeError(f"{name} must be a finite number > 0, got {text!r}")
        return v

    return parse


def _floats(name):
    def parse(text):
        try:
            vals = [float(v) for v in text.split(",") if v.strip()]
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be comma-separated numbers, got {text!r}") from None
        if not vals:
            raise argparse.ArgumentTypeError(f"{name} is empty")
        return vals

    return parse


def _names(text):
    return [v.strip() for v in text.split(",") if v.strip()]


def _sizes(text):
    try:
        vals = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"--sizes must be comma-separated integers, got {text!r}") from None
    if not vals or any(v < 1 for v in vals):
        raise argparse.ArgumentTypeError(f"--sizes must be integers >= 1, got {text!r}")
    return vals


def _choice(name, allowed):
    def parse(text):
        if text not in allowed:
            raise argparse.ArgumentTypeError(f"unknown {name} {text!r}; allowed: {', '.join(allowed)}")
        return text

    return parse


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="icv-envs", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)

    d = sub.add_parser("demo", help="run the four Fig. 7 scenarios with the expert; metrics + GIFs")
    d.add_argument("--out", default="demo_out", help="output directory (default: demo_out)")
    d.add_argument("--seed", type=int, default=0)
    d.add_argument("--seconds", type=_positive_float("--seconds"), default=60.0)
    d.add_argument("--no-video", action="store_true", help="skip the GIFs")

    r = sub.add_parser("run", help="run one episode and print its metrics")
    r.add_argument("env", type=_choice("env", ENVS), help=f"one of: {', '.join(ENVS)}")
    r.add_argument("--scenario", type=_choice("scenario", sorted(SCENARIOS)), default="lane-drop")
    r.add_argument("--policy", type=_choice("policy", POLICIES), default="expert")
    r.add_argument("--seconds", type=_positive_float("--seconds"), default=60.0)
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--out", default=None, help="directory for metrics.json (and video.gif)")
    r.add_argument("--video", action="store_true", help="also write video.gif to --out")
    r.add_argument("--config", default=None, help="JSON dict of extra env config")
    r.add_argument("--method", default="formation", help="highway-ramps: formation, lane-lp or idm")
    r.add_argument("--vgr", type=float, default=1.0 / 3.0, help="highway-ramps: vehicles/s per on-ramp")

    c = sub.add_parser("compare", help="methods x parameters x seeds sweep, in parallel, CSV + plots")
    c.add_argument("target", type=_choice("comparison", COMPARES))
    c.add_argument("--methods", type=_names, default=None,
                   help="highway-ramps: formation,lane-lp,idm (default); intersection: multi-vp,single-vp,fcfs (default)")
    c.add_argument("--throughput", default=None,
                   help="intersection: vehicles/h entering the intersection, comma-separated (default 1000,...,3000)")
    c.add_argument("--lane-use", dest="lane_use", default=None, help="intersection: paper (default) or exclusive")
    c.add_argument("--vgr", type=_floats("--vgr"), default=[0.1, 0.2, 0.33, 0.5])
    c.add_argument("--seeds", type=int, default=3, help="runs use seeds 0..N-1")
    c.add_argument("--seconds", type=float, default=600.0)
    c.add_argument("--out", default="compare_out")
    c.add_argument("--backend", default="process", help="process (local pool, default) or ray")
    c.add_argument("--workers", type=int, default=None, help="local pool size (default: all cores)")

    b = sub.add_parser("bench", help="speed benchmarks (ratios against a reference measured in the same run)")
    b.add_argument("target", type=_choice("benchmark", BENCHES))
    b.add_argument("--sizes", type=_sizes, default=[50, 200, 800])
    b.add_argument("--seconds", type=_positive_float("--seconds"), default=None,
                   help="simulated seconds (highway-formation: per size, default 10; highway-ramps: default 600)")
    b.add_argument("--stock-seconds", type=_positive_float("--stock-seconds"), default=1.0,
                   help="simulated seconds of highway-v0 per size (it is slow)")
    b.add_argument("--vgr", type=float, default=1.0 / 3.0, help="highway-ramps: vehicles/s per on-ramp")
    b.add_argument("--throughput", type=float, default=None, help="intersection: vehicles/h (default 2200: about 60-70 vehicles)")
    b.add_argument("--method", default=None, help="intersection: multi-vp (default), single-vp or fcfs")
    b.add_argument("--vs-sumo", dest="vs_sumo", action="store_true",
                   help="highway-ramps: time the last 100 s beside SUMO on the same ring, alternately (extra 'bench')")
    b.add_argument("--out", default=None, help="also write the JSON to DIR/bench.json")

    from icv_envs.rl.evaluate import add_arguments as _eval_args

    _eval_args(sub.add_parser("evaluate", help="evaluate expert/zero/random or a model saved by baselines/"))
    k = sub.add_parser("conflicts", help="conflict matrix of the 12 intersection movements (derived from the lane use)")
    k.add_argument("--lane-use", dest="lane_use", default="paper", help="paper (default) or exclusive")
    k.add_argument("--json", action="store_true", help="print only the JSON report")
    sub.add_parser("list", help="list environments, scenarios and policies")
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return _dispatch(args)
    except ValueError as exc:
        print(f"icv-envs: error: {exc}", file=sys.stderr)
        return 2


def _dispatch(args) -> int:
    if args.command == "evaluate":
        from icv_envs.rl.evaluate import run

        return run(args)
    if args.command == "list":
        import icv_envs

        out = {"gymnasium": sorted(icv_envs.GYM_IDS), "pettingzoo": sorted(icv_envs.PETTINGZOO_IDS),
               "scenarios": sorted(SCENARIOS), "policies": list(POLICIES)}
        print(json.dumps(out))
        return 0
    if args.command == "run" and args.env == "highway-ramps":
        from icv_envs.experiments.compare import run_ramps, validate_grid

        validate_grid([args.method], [args.vgr], 1, args.seconds)
        m = run_ramps(args.method, args.vgr, args.seed, args.seconds,
                      json.loads(args.config) if args.config else None)
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
    if args.command == "compare" and args.target == "intersection":
        from icv_envs.experiments.intersection_compare import run_cli as compare_intersection_cli

        summary = compare_intersection_cli(args, echo=lambda s: print(s, flush=True))
        print(json.dumps(summary))
        return 0
    if args.command == "compare":
        from icv_envs.experiments.compare import compare_highway_ramps

        args.methods = args.methods or ["formation", "lane-lp", "idm"]

        summary = compare_highway_ramps(args.methods, args.vgr, args.seeds, args.seconds, args.out,
                                        backend=args.backend, workers=args.workers, progress=True)
        for row in summary["table"]:
            print(f"{row['method']:10s} vgr={row['vgr']:<5g} remaining={row['remaining']:7.1f} "
                  f"mean_speed={row['mean_speed']:6.2f} speed_fluctuation={row['speed_fluctuation']:.3f} "
                  f"collisions={row['collisions']} lost={row['lost']}", flush=True)
        summary["out"] = args.out
        print(json.dumps(summary))
        return 0
    if args.command == "run":
        from icv_envs.experiments.run import run_highway_formation

        config = None
        if args.config:
            try:
                config = json.loads(args.config)
            except json.JSONDecodeError as exc:
                raise ValueError(f"--config is not valid JSON: {exc}") from None
            if not isinstance(config, dict):
                raise ValueError(f"--config must be a JSON object, got {args.config!r}")
        if args.video and not args.out:
            raise ValueError("--video needs --out DIR to write the video to")
        m = run_highway_formation(args.scenario, args.policy, args.seconds, args.seed, args.out, args.video,
                                  config, progress=sys.stderr.isatty())
        print(json.dumps(m))
        return 0
    if args.command == "demo":
        from tqdm import tqdm

        from icv_envs.experiments.run import run_highway_formation

        out = Path(args.out)
        results = {}
        for scen in tqdm(["lane-drop", "lane-change", "off-ramp", "on-ramp"], desc="scenarios"):
            m = run_highway_formation(scen, "expert", args.seconds, args.seed, out / scen, not args.no_video)
            results[scen] = m
            tqdm.write(
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

        if args.vs_sumo and args.target != "highway-ramps":
            raise ValueError(f"--vs-sumo is an option of 'bench highway-ramps', not of 'bench {args.target}'")
        if args.target == "intersection":
            from icv_envs.experiments.intersection_bench import run_cli as bench_intersection_cli

            res = bench_intersection_cli(args, echo=lambda s: print(s, flush=True))
        elif args.target == "train":
            from icv_envs.rl.bench import bench_train

            res = bench_train(echo=lambda s: print(s, flush=True))
        elif args.target == "highway-ramps":
            if not 0 < args.vgr <= 1.0:
                raise ValueError(f"--vgr {args.vgr!r}; allowed: 0 < vgr <= 1")
            if args.vs_sumo:
                from icv_envs.experiments.sumo_bench import ramps_vs_sumo

                res = ramps_vs_sumo(args.seconds or 600.0, vgr=args.vgr, echo=lambda s: print(s, flush=True))
            else:
                res = bench_highway_ramps(args.seconds or 600.0, args.vgr, echo=lambda s: print(s, flush=True))
        else:
            res = bench_highway_formation(args.sizes, args.seconds or 10.0, args.stock_seconds,
                                          echo=lambda s: print(s, flush=True))
        if args.out:
            Path(args.out).mkdir(parents=True, exist_ok=True)
            (Path(args.out) / "bench.json").write_text(json.dumps(res, indent=2))
        print(json.dumps(res))
        return 0
    raise ValueError(f"unknown command {args.command!r}")  # pragma: no cover


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
