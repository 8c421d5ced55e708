"""Keep numba's on-disk cache of the compiled kernels in step with their sources.

The kernels are compiled with ``@njit(cache=True)``: numba keeps the machine
code in ``__pycache__`` beside each source file and reuses it while that
file's modification time and size are unchanged. It does not look at the
files of the functions a kernel calls: a kernel in ``frames.py`` that
inlines ``collision_pairs`` from ``neighbours.py`` keeps running the old
``collision_pairs`` after ``neighbours.py`` changes, until ``frames.py``
changes too. In a working copy (an editable install after ``git pull`` or
``git checkout``, where only the changed files get new times) that runs
stale code silently; a ``pip install`` of a release rewrites every file, so
there the stamps change anyway.

:func:`refresh` (run once, when :mod:`icv_envs` is imported, before any
kernel is compiled or loaded) hashes the sources of every kernel module
together and, where the hash differs from the one written beside the cache
the last time, removes the cache indices (``*.nbi``) of the kernel modules in
that directory; numba then compiles afresh and writes new ones. Only the
indices are removed (a missing index is an empty cache to numba; the data
files are overwritten in turn), so a process loading the cache at the same
moment recompiles rather than reading half a file. The directories looked
at are the ones numba's own locators would use for a kernel module: its
``__pycache__``, the directory under ``NUMBA_CACHE_DIR`` when that is set,
and the user-wide cache directory numba falls back to when the package's own
is not writable (each named as numba names it: the source directory's name
and the SHA-1 of its absolute path); directories that do not exist are left
alone. Costs about a millisecond.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

__all__ = ["cache_dirs", "kernel_files", "refresh"]

_ROOT = Path(__file__).resolve().parent
STAMP = "icv_envs_kernels.sha256"


def kernel_files() -> list[Path]:
    """The kernel modules: every ``_kernels.py`` and every module of a
    ``_kernels`` package under :mod:`icv_envs`, sorted."""
    found = set(_ROOT.rglob("_kernels.py")) | {p for d in _ROOT.rglob("_kernels") if d.is_dir() for p in d.glob("*.py")}
    return sorted(found)


def _digest(files: list[Path]) -> str:
    h = hashlib.sha256()
    for f in files:
        h.update(str(f.relative_to(_ROOT)).encode())
        h.update(b"\0")
        h.update(f.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


def refresh() -> list[Path]:
    """Remove the cache indices of kernel modules compiled from other
    sources than the present ones (module docstring). Returns the removed
    files; read-only or missing directories are left as they are."""
    files = kernel_files()
    try:
        digest = _digest(files)
    except OSError:
        return []
    removed: list[Path] = []
    by_dir: dict[Path, list[Path]] = {}
    for f in files:
        by_dir.setdefault(f.parent, []).append(f)
    for d, mods in by_dir.items():
        for cache, in_tree in cache_dirs(d):
            if not in_tree and not cache.is_dir():
                continue
            stamp = cache / STAMP
            try:
                if stamp.read_text() == digest:
                    continue
            except OSError:
                pass
            try:
                for m in mods:
                    for idx in cache.glob(f"{m.stem}.*.nbi"):
                        idx.unlink(missing_ok=True)
                        removed.append(idx)
                cache.mkdir(exist_ok=True)
                stamp.write_text(digest)
            except OSError:
                continue
    return removed


def cache_dirs(src_dir: Path) -> list[tuple[Path, bool]]:
    """Where numba may keep the cache of the kernel modules in ``src_dir``:
    ``(directory, in_tree)`` for its ``__pycache__``, the directory under
    ``NUMBA_CACHE_DIR`` (numba's ``config.CACHE_DIR``, read now) and the
    user-wide one, in numba's naming (``<dir name>_<sha1 of its absolute
    path>``, ``get_suitable_cache_subpath``)."""
    out = [(src_dir / "__pycache__", True)]
    sub = _cache_subpath(src_dir)
    try:
        from numba.core import config

        if config.CACHE_DIR:
            out.append((Path(config.CACHE_DIR) / sub, False))
        from numba.misc.appdirs import AppDirs

        out.append((Path(AppDirs(appname="numba", appauthor=False).user_cache_dir) / sub, False))
    except Exception:  # noqa: BLE001 - a numba without these names: the in-tree cache only
        pass
    return out


def _cache_subpath(src_dir: Path) -> str:
    """numba's ``_CacheLocator.get_suitable_cache_subpath`` for a source file in ``src_dir``."""
    sub = os.path.abspath(str(src_dir))
    return "_".join([os.path.split(sub)[-1], hashlib.sha1(sub.encode()).hexdigest()])
