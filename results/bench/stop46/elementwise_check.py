"""Stop 46: do NumPy's elementwise functions give an element the same result wherever it sits in an array? The
formation expert of many worlds (icv_envs/policies/formation_expert_many.py) calls them once on the worlds'
concatenated arrays instead of once per world. 3,000 random splits of random arrays (1-19 parts of 0-59 values, four
scales); each function on the whole array against the concatenation of its results on the parts, byte for byte.
Prints the number of differing cases (0 on this stop's AMD EPYC VM, AVX-512, NumPy 2.4.6)."""
import numpy as np

rng = np.random.default_rng(0)
fns = {"sinh(arcsinh(a) / 3)": lambda a: np.sinh(np.arcsinh(a) / 3.0), "arctan": np.arctan,
       "a ** 4.0": lambda a: a ** 4.0, "cos": np.cos, "sin": np.sin, "exp": np.exp}
bad = 0
for trial in range(3000):
    sizes = rng.integers(0, 60, size=rng.integers(1, 20))
    parts = [rng.normal(0, rng.choice([0.01, 1, 10, 100]), s) for s in sizes]
    cat = np.concatenate(parts)
    whole = np.hypot(cat, cat * 0.7 + 1)
    sep = np.concatenate([np.hypot(p, p * 0.7 + 1) for p in parts])
    bad += whole.tobytes() != sep.tobytes()
    for name, f in fns.items():
        bad += f(cat).tobytes() != np.concatenate([f(p) for p in parts]).tobytes()
print("differing cases:", bad, "numpy", np.__version__)
