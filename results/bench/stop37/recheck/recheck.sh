R=/work/main/results/bench/stop37/recheck
cd /tmp
PYTHONPATH=/work/main python /work/main/scripts/new_seed_hashes.py /work/main > $R/new_seed_hashes.txt 2>&1
python /work/main/scripts/compare_trees.py /tmp/head /work/main > $R/compare_trees.txt 2>&1
for s in 1 2; do for api in rows dicts; do PYTHONPATH=/work/main python /tmp/s37/recheck.py $api $s 0.333 2>/dev/null | tail -1; done; done > $R/sumo_other_seeds.jsonl
for api in rows dicts; do PYTHONPATH=/work/main python /tmp/s37/recheck.py $api 0 0.2 2>/dev/null | tail -1; done > $R/sumo_vgr02.jsonl
for tree in /tmp/final36 /work/main; do echo "== $tree"; PYTHONPATH=$tree python $tree/scripts/bench_dict_layer.py --vehicles 400 --steps 100 2>&1 | head -2; done > $R/dict_layer_400.txt
echo "== /work/main --info-keys=" >> $R/dict_layer_400.txt; PYTHONPATH=/work/main python /work/main/scripts/bench_dict_layer.py --vehicles 400 --steps 100 --info-keys= >> $R/dict_layer_400.txt 2>&1
python /work/main/scripts/bench_trees.py /tmp/final36 /work/main --case batched --reps 3 > $R/trees_batched.txt 2>&1
python /work/main/scripts/bench_trees.py /tmp/final36 /work/main --case ring --reps 3 > $R/trees_ring.txt 2>&1
echo DONE
