"""Summary of the paired bench windows (int_pairs.py lines; "[test first]"
lines have the trees' roles swapped): per seed the medians of both trees,
and the median of the ratios this tree / stop 46's over all pairs."""
import re, statistics, sys
rows = {}
ratios = []
for path in sys.argv[1:]:
    for line in open(path):
        m = re.search(r"seed (\d+) \((\w+)\): reference ([\d,]+), test ([\d,]+)", line)
        if not m:
            continue
        seed, api = int(m.group(1)), m.group(2)
        a, b = (float(m.group(k).replace(",", "")) for k in (3, 4))
        ours, ref = (a, b) if line.startswith("[test first]") else (b, a)
        rows.setdefault((api, seed), []).append((ours, ref))
        ratios.append(ours / ref)
for (api, seed), v in sorted(rows.items()):
    o = [x for x, _ in v]; r = [y for _, y in v]
    print(f"{api} seed {seed}: {len(v)} pairs; this tree median {statistics.median(o) / 1e3:.1f}k "
          f"({min(o) / 1e3:.1f}-{max(o) / 1e3:.1f}), stop 46's {statistics.median(r) / 1e3:.1f}k ({min(r) / 1e3:.1f}-{max(r) / 1e3:.1f})")
q = sorted(ratios)
print(f"{len(q)} pairs: median ratio {statistics.median(q):.3f}, quartiles {q[len(q) // 4]:.2f}-{q[3 * len(q) // 4]:.2f}")
