"""pyinstrument profile of the batched case's window (stop 47); --expert for the expert."""
import sys
sys.path.insert(0, "/work/main/scripts")
import bench_kernel_boundary as bk
from pyinstrument import Profiler
w = bk._batched("--expert" in sys.argv, 0)
w()
p = Profiler(interval=0.0001)
p.start(); w(); w(); p.stop()
print(p.output_text(unicode=False, show_all=False, color=False))
