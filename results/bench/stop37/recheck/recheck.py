import json, sys
from icv_envs.experiments.sumo_bench import ramps_vs_sumo
api, seed, vgr = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
r = ramps_vs_sumo(600.0, vgr=vgr, seed=seed, api=api, echo=lambda s: None)
print(json.dumps({k: r[k] for k in ("api", "vgr", "icv_vehicles", "sumo_vehicles", "icv_vehicle_steps_per_cpu_s", "sumo_vehicle_steps_per_cpu_s", "ratio_cpu", "collisions", "lost")} | {"seed": seed}))
