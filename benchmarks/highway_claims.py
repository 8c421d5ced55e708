"""The paper's three highway claims (Sec. 6.1) against the LP reference, tested on a sweep.

Reads the ``runs/*.json`` of ``icv-envs compare highway-ramps`` output
directories (or, where a directory has none, as in the committed results
whose ``runs/`` is not in git, its ``results.csv``: one row per run) and prints, per VGR, the formation method's relative difference
to ``lane-lp`` (and to ``idm``) in vehicles remaining on the road at the end,
mean speed and speed fluctuation (mean |dv/dt| of the realised speed), with a
95% Student t interval over seeds of the *per-seed* relative difference (a
seed draws the same arrivals for every method, so the comparison is paired);
writes ``claims.json`` and ``claims.md`` to ``--out``.

The paper's figures: about 30% fewer vehicles remaining, about 30% higher
mean speed, about 60% lower fluctuation.  A claim is *reproduced* when the
interval lies on the claimed side of 0, *contradicted* when it lies on the
other side, *not resolved* otherwise (the size is reported, not judged).

    python benchmarks/highway_claims.py results/highway_ramps --out results/highway_ramps
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

from icv_envs.experiments.intersection_compare import mean_ci as ci

CLAIMS = (("remaining", -1, "about 30% fewer"), ("mean_speed", +1, "about 30% higher"),
          ("speed_fluctuation", -1, "about 60% lower"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--out", default=None)
    ap.add_argument("--against", default="lane-lp,idm")
    a = ap.parse_args(argv)
    runs = {}
    for d in a.dirs:
        found = [json.loads(fp.read_text()) for fp in sorted(Path(d, "runs").glob("*.json"))]
        if not found and Path(d, "results.csv").is_file():
            with open(Path(d, "results.csv"), newline="") as fh:
                found = [{**row, **{k: float(row[k]) for k, _, _ in CLAIMS}} for row in csv.DictReader(fh)]
        if not found:
            raise SystemExit(f"{d}: neither runs/*.json nor results.csv")
        for r in found:
            key = (r["method"], round(float(r["vgr"]), 6), int(r["seed"]))
            if key in runs:
                raise SystemExit(f"run {key} twice")
            runs[key] = r
    vgrs = sorted({k[1] for k in runs})
    out = {"claims": []}
    lines = ["| claim (formation vs ref.) | paper | VGR | ref. | ours: relative difference, seed mean +- 95% CI | seeds | reproduced? |",
             "|---|---|---:|---|---|---:|---|"]
    for key, sign, paper in CLAIMS:
        for vgr in vgrs:
            for ref in a.against.split(","):
                seeds = sorted(s for (m, v, s) in runs if m == "formation" and v == vgr and (ref, v, s) in runs)
                if not seeds:
                    continue
                rel = [runs[("formation", vgr, s)][key] / runs[(ref, vgr, s)][key] - 1.0 for s in seeds]
                m, h = ci(rel)
                verdict = "not resolved"
                if h is not None and sign * (m - sign * h) > 0:
                    verdict = "yes (direction)"
                elif h is not None and sign * (m + sign * h) < 0:
                    verdict = "no (reversed)"
                out["claims"].append({"metric": key, "vgr": vgr, "against": ref, "seeds": seeds, "relative": m,
                                      "ci95": h, "verdict": verdict})
                txt = f"{100 * m:+.1f}%" + ("" if h is None else f" +- {100 * h:.1f}%")
                lines.append(f"| {key} | {paper} | {vgr:g} | {ref} | {txt} | {len(seeds)} | {verdict} |")
    md = "\n".join(lines)
    print(md)
    dest = Path(a.out or a.dirs[0])
    (dest / "claims.json").write_text(json.dumps(out, indent=1))
    (dest / "claims.md").write_text(md + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
