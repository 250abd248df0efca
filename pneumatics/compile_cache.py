"""Numba's on-disk cache, keyed by the contents of every compiled source file.

numba (``cache=True``) keys a cached function by a hash of its *own* file
(``numba.core.caching._SourceFileBackedLocatorMixin.get_source_stamp``), not of the files
whose functions it compiles into itself.  pneumasim's hot loops cross files: the C entry
point of ``step_call.py`` and the closed loop of ``controllers/compiled_loop.py`` compile
``kernel.py``'s physics step into themselves, the doctor's chamber replay its orifice flow.
After an update that changes ``kernel.py`` alone, those loops would load their old machine
code from the cache and run the old physics.

So the cache folder is named by a hash of every project source file that mentions numba and
of the project modules those import from: change any of them and every compiled function is
compiled afresh (once), into a new folder.  :func:`key_the_cache` sets ``numba.config.CACHE_DIR`` and must run before the first
``@numba.njit(cache=True)`` is decorated: ``pneumatics/__init__.py`` calls it, and every
compiled module imports :mod:`pneumatics` first.  A user's ``NUMBA_CACHE_DIR`` is kept as
the parent folder; otherwise the folder lies under ``$XDG_CACHE_HOME`` (``~/.cache``).
Folders of other source versions unused for ``KEEP_DAYS`` are removed.
"""
from __future__ import annotations

import hashlib
import os
import re
import shutil
import time
from pathlib import Path

#: the project's packages whose modules may hold compiled code
PACKAGES = ("pneumatics", "controllers", "identification", "scenarios", "workflow", "pneumasim")
#: other source versions' cache folders are removed after this many days unused
KEEP_DAYS = 14
PREFIX = "pneumasim-"


#: ``from .x import``, ``from ..x import``, ``from . import x``, ``from pneumatics.x import``
_IMPORT = re.compile(rb"^from\s+(\.+)?([\w.]*)\s+import\s+\(?([\w, ]*)", re.MULTILINE)


def source_key(root: Path) -> str:
    """16 hex digits of a SHA-256 over the path and text of every ``*.py`` under ``root``'s
    PACKAGES that mentions numba, and of the project modules those import from (compiled code
    freezes the constants it reads from them, e.g. the polynomial's degree in kernel.py)."""
    compiled = [p for package in PACKAGES for p in sorted((root / package).rglob("*.py")) if b"numba" in p.read_bytes()]
    files = set(compiled)
    for path in compiled:
        files.update(_imported(path, root))
    digest = hashlib.sha256()
    for path in sorted(files):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _imported(path: Path, root: Path) -> list[Path]:
    """The project's source files that ``path`` imports from (one level)."""
    out = []
    for dots, module, names in _IMPORT.findall(path.read_bytes()):
        if dots:
            base = path.parent
            for _ in range(len(dots) - 1):
                base = base.parent
        elif module.split(b".")[0].decode() in PACKAGES:
            base = root
        else:
            continue
        target = base.joinpath(*module.decode().split(".")) if module else base
        candidates = [target.with_suffix(".py"), target / "__init__.py"]
        if not module:  # from . import a, b: the modules a and b
            candidates = [base / f"{n.split()[0]}.py" for n in names.decode().split(",") if n.strip()]
        out += [c for c in candidates if c.is_file()]
    return out


def cache_parent() -> Path:
    """The folder that holds one cache folder per source version."""
    given = os.environ.get("NUMBA_CACHE_DIR")
    if given:
        return Path(given)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "pneumasim" / "numba"


def key_the_cache() -> Path | None:
    """Point numba's cache at the folder of the current sources; returns it (None where no
    folder can be written: numba then compiles without a cache, as it does by itself)."""
    import numba

    root = Path(__file__).resolve().parent.parent
    folder = cache_parent() / f"{PREFIX}{source_key(root)}"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        os.utime(folder)  # marks it used, for the pruning of other versions
    except OSError:
        return None
    numba.config.CACHE_DIR = str(folder)
    _prune(folder)
    return folder


def _prune(current: Path) -> None:
    cutoff = time.time() - KEEP_DAYS * 86400
    for other in current.parent.glob(f"{PREFIX}*"):
        try:
            if other != current and other.stat().st_mtime < cutoff:
                shutil.rmtree(other, ignore_errors=True)
        except OSError:
            pass  # another process removed it first
