"""numba's cache folder follows the contents of every compiled source file."""
import os
import time
from pathlib import Path

import numba

import pneumatics
from pneumatics import compile_cache


def _tree(root: Path, kernel: str, other: str):
    (root / "pneumatics").mkdir(parents=True, exist_ok=True)
    (root / "pneumatics" / "kernel.py").write_text(kernel)
    (root / "pneumatics" / "notes.py").write_text(other)


def test_the_key_changes_with_a_compiled_file_and_only_with_one(tmp_path):
    _tree(tmp_path, "import numba\nX = 1\n", "Y = 1\n")
    first = compile_cache.source_key(tmp_path)
    _tree(tmp_path, "import numba\nX = 1\n", "Y = 2\n")  # no numba in it: same cache
    assert compile_cache.source_key(tmp_path) == first
    _tree(tmp_path, "import numba\nX = 2\n", "Y = 2\n")  # a compiled file changed: new cache
    assert compile_cache.source_key(tmp_path) != first


def test_the_key_follows_the_modules_compiled_code_imports_from(tmp_path):
    """Compiled code freezes the constants it imports (kernel.py's polynomial degree from
    flow_polynomial.py): a change there must change the key, one elsewhere must not."""
    _tree(tmp_path, "import numba\nfrom .notes import Y\nfrom . import (consts)\n", "Y = 1\n")
    (tmp_path / "pneumatics" / "consts.py").write_text("C = 1\n")
    (tmp_path / "pneumatics" / "other.py").write_text("Z = 1\n")
    first = compile_cache.source_key(tmp_path)
    (tmp_path / "pneumatics" / "other.py").write_text("Z = 2\n")
    assert compile_cache.source_key(tmp_path) == first
    (tmp_path / "pneumatics" / "consts.py").write_text("C = 2\n")
    second = compile_cache.source_key(tmp_path)
    assert second != first
    (tmp_path / "pneumatics" / "notes.py").write_text("Y = 2\n")
    assert compile_cache.source_key(tmp_path) != second


def test_importing_pneumatics_points_numba_at_the_current_sources():
    root = Path(pneumatics.__file__).resolve().parent.parent
    folder = Path(numba.config.CACHE_DIR)
    assert folder.name == compile_cache.PREFIX + compile_cache.source_key(root)
    assert folder.is_dir()


def test_a_users_cache_folder_is_kept_as_parent_and_stale_versions_go(tmp_path, monkeypatch):
    old, recent = tmp_path / "pneumasim-old", tmp_path / "pneumasim-recent"
    old.mkdir()
    recent.mkdir()
    month_ago = time.time() - 30 * 86400
    os.utime(old, (month_ago, month_ago))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(numba.config, "CACHE_DIR", numba.config.CACHE_DIR)  # restored afterwards
    folder = compile_cache.key_the_cache()
    assert folder.parent == tmp_path and Path(numba.config.CACHE_DIR) == folder
    assert not old.exists() and recent.exists()
