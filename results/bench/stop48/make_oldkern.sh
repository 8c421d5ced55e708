#!/usr/bin/env bash
# Copies of a reference tree's frame kernels as a package "oldkern" for ab_frames.py and ab_ring.py (stop 48):
# frames.py with the intersection's, the statistics' and the neighbours' kernels it calls.
# Usage: make_oldkern.sh REF OUT_DIR
set -eu
mkdir -p "$2/oldkern" && touch "$2/oldkern/__init__.py"
for m in frames intersection stats neighbours; do cp "$1/icv_envs/sim/_kernels/$m.py" "$2/oldkern/$m.py"; done
sed -i 's/from icv_envs.sim._kernels.intersection import/from oldkern.intersection import/; s/from icv_envs.sim._kernels.stats import/from oldkern.stats import/; s/from icv_envs.sim._kernels.neighbours import/from oldkern.neighbours import/' "$2/oldkern/frames.py" "$2/oldkern/intersection.py"
