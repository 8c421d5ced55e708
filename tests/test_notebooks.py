"""The notebooks in notebooks/ run top to bottom without errors (small
settings: ``ICV_NB_FAST=1``, models written to a temporary ``ICV_NB_OUT``).

Needs ``nbclient``, ``nbformat`` and ``ipykernel`` (the ``test`` extra); the
tests skip without them. The kernel is this interpreter (``sys.executable``),
through a temporary ``python3`` kernelspec put first on ``JUPYTER_PATH``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = ROOT / "notebooks"


@pytest.fixture
def kernel_env(tmp_path, monkeypatch):
    """A ``python3`` kernelspec running this interpreter, and the notebooks' switches."""
    spec_dir = tmp_path / "jupyter" / "kernels" / "python3"
    spec_dir.mkdir(parents=True)
    (spec_dir / "kernel.json").write_text(json.dumps({
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": "Python 3 (tests)", "language": "python",
    }))
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path / "jupyter"))
    monkeypatch.setenv("ICV_NB_FAST", "1")
    monkeypatch.setenv("ICV_NB_OUT", str(tmp_path / "models"))
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    monkeypatch.setenv("SDL_AUDIODRIVER", "dummy")
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    return tmp_path


def run_notebook(name: str, cwd=NOTEBOOKS):
    """Execute notebooks/<name> in a fresh python3 kernel (working directory
    ``cwd``); returns the executed notebook."""
    nb = nbformat.read(NOTEBOOKS / name, as_version=4)
    client = nbclient.NotebookClient(nb, kernel_name="python3", timeout=300,
                                     resources={"metadata": {"path": str(cwd)}})
    client.execute()
    return nb


def outputs(nb):
    return [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]


def text_of(nb) -> str:
    parts = []
    for o in outputs(nb):
        parts.append(o.get("text", ""))
        parts.append(o.get("data", {}).get("text/plain", ""))
        parts.append(o.get("data", {}).get("text/html", ""))
    return "\n".join(parts)


def test_notebooks_are_valid_and_unexecuted():
    for path in sorted(NOTEBOOKS.glob("*.ipynb")):
        nb = nbformat.read(path, as_version=4)
        nbformat.validate(nb)
        assert nb.metadata["kernelspec"]["name"] == "python3"
        assert not outputs(nb), f"{path.name} is stored with outputs; clear them"
    assert {p.name for p in NOTEBOOKS.glob("*.ipynb")} >= {"quickstart.ipynb", "expert_vs_learned.ipynb"}


def test_quickstart(kernel_env):
    nb = run_notebook("quickstart.ipynb")
    images = [o for o in outputs(nb) if "image/png" in o.get("data", {})]
    assert len(images) == 2  # lane-drop frames, on-ramp frames
    text = text_of(nb)
    assert "observation (8, 13) float32" in text
    assert "expert_action" in text
    for metric in ("collisions", "mean_speed", "speed_fluctuation", "min_gap"):
        assert metric in text


def test_expert_vs_learned(kernel_env):
    pytest.importorskip("torch")
    pytest.importorskip("stable_baselines3")
    elsewhere = kernel_env / "elsewhere"  # not inside the repository: runs from any directory
    elsewhere.mkdir()
    nb = run_notebook("expert_vs_learned.ipynb", cwd=elsewhere)
    models = kernel_env / "models"
    for name in ("bc", "ppo"):
        assert (models / name / "model.zip").is_file()
        assert json.loads((models / name / "run.json").read_text())["config"]["duration"] == 10.0
    text = text_of(nb)
    for token in ("expert", "zero", "bc", "ppo", "lane-drop", "on-ramp", "collisions", "episode_return"):
        assert token in text
    assert any("image/png" in o.get("data", {}) for o in outputs(nb))  # the bar plots
