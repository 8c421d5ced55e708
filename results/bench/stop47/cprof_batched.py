"""cProfile (tottime) of the batched case, learned (zero) actions (stop 47)."""
import cProfile, pstats, sys
sys.path.insert(0, "/work/main/scripts")
import bench_kernel_boundary as bk
w = bk._batched("--expert" in sys.argv, 0)
w()
pr = cProfile.Profile()
pr.enable(); w(); pr.disable()
pstats.Stats(pr).sort_stats("tottime").print_stats(45)
