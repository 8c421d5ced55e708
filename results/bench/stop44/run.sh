#!/usr/bin/env bash
# Stop 44: every figure the README states for this stop, from a fresh run on the final code against stop 43's final tree
# (214216e), alternately: stop 43's fresh run (results/bench/stop43/fresh/run.sh, the same figures and unseen settings),
# then the kernel-boundary analysis (scripts/bench_kernel_boundary.py) on both trees.
# Usage, from outside the checkout: run.sh REF TEST OUT  (REF: stop 43's final tree 214216e)
set -u
REF=$1; TEST=$2; OUT=$3; D=$(cd "$(dirname "$0")" && pwd); S=$D/../../../scripts
bash "$D/../stop43/fresh/run.sh" "$REF" "$TEST" "$OUT"
OUT=$(cd "$OUT" && pwd)
cd /tmp
for t in $REF $TEST; do
  echo "== $t" >> $OUT/kernel_boundary.txt
  PYTHONPATH=$t python $S/bench_kernel_boundary.py --out $OUT/kernel_boundary_$(basename $t).json >> $OUT/kernel_boundary.txt 2>&1
done
