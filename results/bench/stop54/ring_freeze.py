"""Stop 54: `icv-envs bench highway-ramps --vs-sumo` (dicts) with gc.freeze() called once, after our 500 s warm-up
(just before SUMO starts): the objects alive then (the libraries' ~222k, the env) are never walked by a full
collection again. Run: PYTHONPATH=<tree> python ring_freeze.py [freeze|plain]"""
import gc
import json
import sys

from icv_envs.experiments import sumo_bench, sumo_ring

if sys.argv[1:] == ["freeze"]:
    orig = sumo_ring.SumoRing.__init__

    def init(self, *a, **k):
        gc.freeze()
        orig(self, *a, **k)

    sumo_ring.SumoRing.__init__ = init
res = sumo_bench.ramps_vs_sumo(api="dicts")
print(json.dumps(res))
