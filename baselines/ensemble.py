"""An ensemble of saved models: the mean of the members' deterministic actions (continuous), or the
action of largest mean probability (discrete: soft voting).

    python baselines/ensemble.py --members results/learned/A,results/learned/B --out results/learned/A_B_ensemble
    icv-envs evaluate --env intersection_v0 --policy results/learned/A_B_ensemble --episodes 8

The members (directories written by ``bc_expert.py`` or ``ppo_recipe.py``
with continuous or discrete actions) must share the env, its config and the spaces;
``OUT/run.json`` names them relative to ``OUT`` and nothing is trained.
Averaging independently trained regressors is the plain variance
reduction of bagging: it costs one forward pass per member and needs no
choice of weights. Prints the ensemble's ``run.json`` as one JSON line.
"""

from __future__ import annotations

import argparse
import json
import sys

from icv_envs.rl.models import write_ensemble


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--members", required=True, help="model directories, comma-separated (at least two)")
    p.add_argument("--out", required=True, help="the ensemble's directory")
    a = p.parse_args(argv)
    members = [m.strip() for m in a.members.split(",") if m.strip()]
    try:
        path = write_ensemble(a.out, members)
    except ValueError as exc:
        print(f"ensemble.py: error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(json.loads(path.read_text())))
    return 0


if __name__ == "__main__":
    sys.exit(main())
