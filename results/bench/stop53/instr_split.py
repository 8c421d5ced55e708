"""Where a batched world-step's instructions go, by the object that runs them (stop 53): CPython's interpreter
(``libpython`` / the ``python`` binary), NumPy's and SciPy's extension modules, numba's compiled kernels (code in
anonymous memory, no object file: ``???``), libm, libc and the rest. Counted by valgrind's callgrind with only the
timed steps instrumented (``instr_count.py``'s child), then each function's exclusive instructions summed per object.

    python results/bench/stop53/instr_split.py TREE [--kind zero|noisy|uniform] [--steps 100]

Prints the shares and a JSON line.
"""
import argparse
import json
import os
import re
import sys
import tempfile
from collections import Counter

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from instr_count import run_counted  # noqa: E402  (the same child and handshake)


def split(path: str) -> Counter:
    """Exclusive instructions per object of a callgrind output file (``ob=`` sets the object of the ``fn=`` lines
    after it; the cost line after ``calls=`` is the callee's inclusive cost and is not this function's)."""
    names: dict[str, str] = {}
    out = Counter()
    ob = "?"
    skip = False
    pat = re.compile(r"^\((\d+)\)(?: (.*))?$")
    with open(path) as fh:
        for line in fh:
            if line.startswith("ob="):
                m = pat.match(line[3:].strip())
                if m:
                    if m.group(2):
                        names[m.group(1)] = m.group(2)
                    ob = names.get(m.group(1), "?")
                else:
                    ob = line[3:].strip()
            elif line.startswith(("cob=", "cfn=", "cfi=", "cfl=")):
                m = pat.match(line.split("=", 1)[1].strip())
                if line.startswith("cob=") and m and m.group(2):
                    names[m.group(1)] = m.group(2)
            elif line.startswith("calls="):
                skip = True
            elif line[:1].isdigit() or line[:1] in "+-*":
                if skip:
                    skip = False
                    continue
                parts = line.split()
                if len(parts) >= 2:
                    out[ob] += int(parts[1])
    return out


def group(obj: str) -> str:
    base = os.path.basename(obj)
    if obj in ("???", "?") or not base:
        return "numba's compiled kernels (anonymous code)"
    if "libpython" in base or base.startswith("python"):
        return "CPython interpreter"
    if "_multiarray_umath" in base or "numpy" in obj:
        return "NumPy"
    if "scipy" in obj:
        return "SciPy"
    if base.startswith("libm"):
        return "libm"
    if base.startswith("libc") or base.startswith("ld-linux"):
        return "libc / loader"
    if "numba" in obj:
        return "numba's runtime (dispatch, boxing)"
    return base


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("tree")
    p.add_argument("--kind", default="zero", choices=("zero", "noisy", "uniform"))
    p.add_argument("--steps", type=int, default=100)
    p.add_argument("--warm", type=int, default=100)
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as d:
        run_counted(a.tree, a.kind, a.steps, a.warm, d)
        by_obj = split(os.path.join(d, "cg.out"))
    groups = Counter()
    for obj, n in by_obj.items():
        groups[group(obj)] += n
    total = sum(groups.values())
    ws = 16 * a.steps
    print(f"{a.kind}: {total / ws:,.0f} instructions a world-step")
    for g, n in groups.most_common():
        print(f"  {100 * n / total:5.1f}%  {n / ws:10,.0f}  {g}")
    print(json.dumps({"kind": a.kind, "steps": a.steps, "per_world_step": total / ws,
                      "shares": {g: n / total for g, n in groups.most_common()},
                      "objects": {o: n / ws for o, n in by_obj.most_common(20)}}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
