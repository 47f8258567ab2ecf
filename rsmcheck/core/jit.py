"""Where numba keeps the compiled kernels: a folder per version of the sources.

numba's own cache (`@njit(cache=True)`) checks only the file that defines a function: a
cached right-hand side that calls or inlines a kernel of another module is not recompiled
when that module changes, and runs the old physics.  For a suite whose users change the
model and rerun it, that is a wrong answer, not a slow one.  So the cache lives in a
folder named after a digest of every source file of rsmcheck and of the engine plug-ins
registered with it (entry-point group `rsmcheck.engines`) that use numba: any change of any
of them compiles afresh, an unchanged tree reuses its kernels, and installing a plug-in
without kernels of its own (one that drives an in-tree engine) compiles nothing again.

`use_source_keyed_cache()` sets it, once, before the first kernel is decorated; every
package with compiled kernels calls it in its `__init__` (only those import this module,
and with it numba).  NUMBA_CACHE_DIR, when set,
is the user's choice and is left alone.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import re
from importlib import metadata
from pathlib import Path

import numba

_DONE = False


#: a line that imports numba (alone or among others) or points numba's cache here
_IMPORTS_NUMBA = re.compile(rb"^\s*(?:from numba\b|import\b[^#\n]*\bnumba\b)|\buse_source_keyed_cache\(", re.M)


def _compiles(folder: Path) -> bool:
    """Whether a package folder can hold a numba kernel: one of its .py files imports numba.
    A kernel calls only compiled functions, so a package that never imports numba (a plug-in
    that drives another package's engine) cannot make a cached kernel stale."""
    return any(_IMPORTS_NUMBA.search(p.read_bytes()) for p in folder.rglob("*.py"))


def _package_dirs() -> list[Path]:
    """rsmcheck's folder and the folder of every registered engine plug-in's top package
    that can hold kernels (`_compiles`)."""
    dirs = [Path(__file__).resolve().parents[1]]
    for ep in metadata.entry_points(group="rsmcheck.engines"):
        spec = importlib.util.find_spec(ep.value.split(":")[0].split(".")[0])
        if spec is not None and spec.submodule_search_locations:
            dirs += [Path(p).resolve() for p in spec.submodule_search_locations if _compiles(Path(p))]
    return sorted(set(dirs))


def source_key() -> str:
    """Digest of the names and contents of every .py file of the packages above."""
    h = hashlib.sha256()
    for d in _package_dirs():
        for p in sorted(d.rglob("*.py")):
            h.update(str(p.relative_to(d.parent)).encode())
            h.update(p.read_bytes())
    return h.hexdigest()[:16]


def cache_root() -> Path:
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "rsmcheck" / "numba"


def use_source_keyed_cache() -> None:
    """Point numba's cache at cache_root()/source_key() unless NUMBA_CACHE_DIR is set."""
    global _DONE
    if _DONE or os.environ.get("NUMBA_CACHE_DIR"):
        _DONE = True
        return
    numba.config.CACHE_DIR = str(cache_root() / source_key())
    _DONE = True


def cache_dir() -> Path:
    """The folder numba keeps the kernels in (after `use_source_keyed_cache`)."""
    use_source_keyed_cache()
    return Path(numba.config.CACHE_DIR)
