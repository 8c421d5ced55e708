"""Load a ``baselines/*.py`` training script as a module (the scripts are
CleanRL-style single files, not part of the package)."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def load_baseline(name: str):
    """``baselines/<name>.py`` as a module named ``baseline_<name>``."""
    spec = importlib.util.spec_from_file_location(f"baseline_{name}", ROOT / "baselines" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
