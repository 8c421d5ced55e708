"""pyinstrument profile of the intersection bench's window (stop 47)."""
import sys
sys.path.insert(0, "/work/main/scripts")
import bench_kernel_boundary as bk
from pyinstrument import Profiler
w = bk._intersection(0)
p = Profiler(interval=0.0002)
p.start(); w(); p.stop()
print(p.output_text(unicode=False, show_all=False, color=False))
