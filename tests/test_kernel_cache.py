"""The guard against stale numba caches (icv_envs/_kernel_cache.py): numba
reuses a kernel's cached machine code while the kernel's own file is
unchanged, even when a kernel it calls (in another file) changed."""

from __future__ import annotations

from pathlib import Path

from icv_envs import _kernel_cache


def test_kernel_files_are_every_module_compiled_with_a_cache():
    root = Path(_kernel_cache.__file__).resolve().parent
    cached = {p for p in root.rglob("*.py") if "cache=True" in p.read_text() and p.name != "_kernel_cache.py"}
    assert set(_kernel_cache.kernel_files()) == cached


def test_numba_names_its_indices_as_the_guard_expects():
    """The guard removes ``<module stem>.*.nbi``: the names numba gives the
    index of a kernel compiled here."""
    from icv_envs.sim._kernels import npy_mod

    assert npy_mod(3.0, 2.0) == 1.0
    cache = Path(_kernel_cache.__file__).resolve().parent / "sim" / "_kernels" / "__pycache__"
    assert list(cache.glob("physics.npy_mod-*.nbi"))


def test_refresh_drops_the_indices_once_any_kernel_source_changes(tmp_path, monkeypatch):
    root = tmp_path / "icv_envs"
    (root / "sim" / "_kernels").mkdir(parents=True)
    (root / "policies").mkdir()
    a = root / "sim" / "_kernels" / "frames.py"
    b = root / "sim" / "_kernels" / "neighbours.py"
    c = root / "policies" / "_kernels.py"
    other = root / "policies" / "expert.py"
    for f in (a, b, c, other):
        f.write_text(f"# {f.name}\n")
    monkeypatch.setattr(_kernel_cache, "_ROOT", root)
    assert _kernel_cache.kernel_files() == sorted([a, b, c])

    def indices():
        made = []
        for f in (a, b, c, other):
            d = f.parent / "__pycache__"
            d.mkdir(exist_ok=True)
            for name in (f"{f.stem}.kernel-10.py311.nbi", f"{f.stem}.kernel-10.py311.1.nbc"):
                (d / name).write_bytes(b"x")
                made.append(d / name)
        return made

    made = indices()
    first = _kernel_cache.refresh()  # no stamp yet: every kernel index goes
    assert sorted(first) == sorted(p for p in made if p.suffix == ".nbi" and "expert" not in p.name)
    assert _kernel_cache.refresh() == []  # same sources: nothing removed
    indices()
    assert _kernel_cache.refresh() == []
    b.write_text("# neighbours.py, changed\n")  # a callee changes: the callers' indices go too
    gone = _kernel_cache.refresh()
    assert {p.name for p in gone} == {"frames.kernel-10.py311.nbi", "neighbours.kernel-10.py311.nbi",
                                      "_kernels.kernel-10.py311.nbi"}
    assert all(not p.exists() for p in gone)
    assert (other.parent / "__pycache__" / "expert.kernel-10.py311.nbi").exists()  # not a kernel module
    assert all(p.exists() for p in made if p.suffix == ".nbc")  # data files stay (numba overwrites them)


def test_refresh_leaves_a_read_only_tree_alone(tmp_path, monkeypatch):
    """Where the cache directory cannot be written (an install numba keeps
    its cache elsewhere for), refresh neither fails nor removes anything."""
    root = tmp_path / "icv_envs"
    (root / "formation").mkdir(parents=True)
    (root / "formation" / "_kernels.py").write_text("# k\n")
    monkeypatch.setattr(_kernel_cache, "_ROOT", root)

    def refuse(self, *args, **kwargs):
        raise PermissionError(f"read-only: {self}")

    monkeypatch.setattr(Path, "mkdir", refuse)
    assert _kernel_cache.refresh() == []
    assert not (root / "formation" / "__pycache__").exists()


def test_refresh_also_drops_stale_indices_under_numba_cache_dir(tmp_path, monkeypatch):
    """With ``NUMBA_CACHE_DIR`` set numba keeps the cache there, in a
    directory per source directory; the guard looks there too (and creates
    no such directory where numba made none)."""
    from numba.core import config

    root = tmp_path / "icv_envs"
    (root / "sim" / "_kernels").mkdir(parents=True)
    (root / "policies").mkdir()
    a = root / "sim" / "_kernels" / "frames.py"
    b = root / "policies" / "_kernels.py"
    for f in (a, b):
        f.write_text(f"# {f.name}\n")
    monkeypatch.setattr(_kernel_cache, "_ROOT", root)
    ext = tmp_path / "numba_cache"
    monkeypatch.setattr(config, "CACHE_DIR", str(ext))
    outside = ext / _kernel_cache._cache_subpath(a.parent)
    outside.mkdir(parents=True)
    idx = outside / "frames.kernel-10.py311.nbi"
    idx.write_bytes(b"x")
    assert (outside, False) in _kernel_cache.cache_dirs(a.parent)
    gone = _kernel_cache.refresh()
    assert idx in gone and not idx.exists()
    assert (outside / _kernel_cache.STAMP).exists()
    assert not (ext / _kernel_cache._cache_subpath(b.parent)).exists()  # numba made none: none made here
    idx.write_bytes(b"x")
    assert _kernel_cache.refresh() == []  # same sources: kept
    a.write_text("# frames.py, changed\n")
    assert idx in _kernel_cache.refresh()


def test_numba_names_its_cache_dir_as_the_guard_expects(tmp_path):
    """A kernel compiled with ``NUMBA_CACHE_DIR`` set writes its index into
    the directory :func:`cache_dirs` names (a fresh process: numba reads the
    variable at import)."""
    import os
    import subprocess
    import sys

    from icv_envs.sim._kernels import physics

    code = "from icv_envs.sim._kernels import npy_mod; assert npy_mod(3.0, 2.0) == 1.0"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=600)
    where = Path(physics.__file__).resolve().parent
    assert list((tmp_path / _kernel_cache._cache_subpath(where)).glob("physics.npy_mod-*.nbi"))
