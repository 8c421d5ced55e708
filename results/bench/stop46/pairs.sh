#!/bin/sh
# Paired runs of batched_expert_speed.py on two trees, alternately, in both orders:
#   sh pairs.sh REF_TREE TEST_TREE REPS [batched_expert_speed.py options...]
ref=$1; test=$2; reps=$3; shift 3
here=$(cd "$(dirname "$0")" && pwd)
i=0
while [ $i -lt "$reps" ]; do
  if [ $((i % 2)) -eq 0 ]; then order="$ref $test"; else order="$test $ref"; fi
  for t in $order; do
    if [ "$t" = "$ref" ]; then tag=ref; else tag=test; fi
    printf '%s ' "$tag"; (cd /tmp && PYTHONPATH="$t" python "$here/batched_expert_speed.py" "$@")
  done
  i=$((i + 1))
done
