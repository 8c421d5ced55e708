#!/usr/bin/env bash
# Copies of a reference tree's frame kernels as a package "oldkern" for ab_frames.py (stop 48).
# Usage: make_oldkern.sh REF OUT_DIR
set -eu
mkdir -p "$2/oldkern" && touch "$2/oldkern/__init__.py"
for m in frames intersection stats; do cp "$1/icv_envs/sim/_kernels/$m.py" "$2/oldkern/$m.py"; done
sed -i 's/from icv_envs.sim._kernels.intersection import/from oldkern.intersection import/; s/from icv_envs.sim._kernels.stats import/from oldkern.stats import/' "$2/oldkern/frames.py"
