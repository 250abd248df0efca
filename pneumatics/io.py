"""Output discipline: no result is ever lost, half-written or mixed with an earlier run's.

Every command (run, doctor, import, sweep, bench) writes through this module:

* :class:`OutputFolder` — a command's ``--out`` folder.  Checked before any work (a file, a
  read-only folder, a folder holding the command's input or files pneumasim did not write
  are refused with :class:`~pneumatics.errors.OutputError`); the run writes into a staging
  folder beside the target (``.<name>.partial-<pid>-<random>``); at the end the staging
  folder is swapped in whole (one ``renameat2(RENAME_EXCHANGE)`` on Linux) and the previous
  folder removed.  A run that fails or is interrupted leaves the previous results untouched
  and no file of an earlier run stays beside new ones.  Files named outside the folder (an
  ``.rrd`` given to ``--rerun``) are written to a temporary name beside their target and moved
  into place after the swap (:meth:`OutputFolder.file`).
* Resumable runs (sweeps) keep their staging folder, ``.<name>.partial``, when they fail or are
  interrupted: its per-case files are the resume state, and a rerun with the same ``--out``
  continues in it.  A fresh staging folder starts as a hard-link copy of the previous complete
  results, so a rerun reuses their finished cases too.  The target is still replaced only when
  the whole run has finished.
* :class:`OutputFiles` — the same for single files (``pneumasim import``: a recording and its
  sidecar): written beside their targets, all moved into place at the end.
* :func:`atomic_write_text` and friends — one file, replaced whole.

Files follow the user's umask (0644 under umask 022), like any program's output.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import json
import os
import re
import shutil
import tempfile
from pathlib import Path

from .errors import OutputError
from .stopping import raise_if_stopped, stop_received

#: written into every output folder at the swap: marks it as one pneumasim may replace whole
MARKER = ".pneumasim-output"
#: a folder holding one of these came from pneumasim (written before the marker existed)
SIGNATURE_FILES = ("metrics.json", "report.json", "bench.json", "sweep.json", "results.json")


# ---------------------------------------------------------------- single files

def current_umask() -> int:
    """The process's umask (read by setting it and putting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def file_mode() -> int:
    """Mode of a new file under the current umask: 0o666 & ~umask (0o644 under 022)."""
    return 0o666 & ~current_umask()


def folder_mode() -> int:
    return 0o777 & ~current_umask()


def atomic_write_text(path: str | Path, text: str):
    """Write ``path`` whole or not at all; the file follows the umask (mkstemp's own 0600 would
    hide results in a shared folder)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        if hasattr(os, "fchmod"):  # POSIX
            os.fchmod(fd, file_mode())
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_json(path: str | Path, obj):
    atomic_write_text(path, json.dumps(obj, indent=1, sort_keys=False) + "\n")


def atomic_save(path: str | Path, save):
    """Call ``save(tmp_path)`` (e.g. ``fig.savefig``) and move the result into place."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    try:
        save(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


# ---------------------------------------------------------------- checks

def _nearest_existing(path: Path) -> Path:
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def check_writable_place(target: Path, option: str):
    """``target``'s folder can be created and written (the nearest existing ancestor is a
    writable folder)."""
    anchor = _nearest_existing(target.parent)
    if not anchor.is_dir():
        raise OutputError(f"{option} {target}: {anchor} is a file, not a folder")
    if not os.access(anchor, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {target}: cannot create files in {anchor} (permission denied or read-only)")


def _inside(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def check_output_folder(target: str | Path, inputs=(), option: str = "--out") -> Path:
    """Refuse, before any work, an output folder the run could not write or must not replace."""
    target = Path(target).expanduser()
    if str(target).strip() == "":
        raise OutputError(f"{option}: empty path; expected a folder")
    if target.is_symlink():  # swap at the folder the link names, and keep the link
        target = target.resolve()
    where = target.resolve()
    if target.exists() and not target.is_dir():
        raise OutputError(f"{option} {target}: is a file; expected a folder (it is replaced whole by the results)")
    check_writable_place(target, option)
    for item in inputs:
        if _inside(Path(item).expanduser().resolve(), where):
            raise OutputError(f"{option} {target}: holds the input {item}; the results replace the whole "
                              f"folder, so give a folder of its own (e.g. {target / 'results'})")
    if _inside(Path.cwd().resolve(), where) or where == Path.home().resolve():
        raise OutputError(f"{option} {target}: is the current or home folder (or holds it); the results "
                          "replace the whole folder, so give a folder of its own")
    if target.is_dir():
        if not os.access(target, os.W_OK | os.X_OK):
            raise OutputError(f"{option} {target}: the folder is read-only")
        foreign = _foreign_files(target)
        if foreign:
            raise OutputError(f"{option} {target}: holds files pneumasim did not write ({', '.join(foreign[:3])}"
                              f"{' ...' if len(foreign) > 3 else ''}); the results replace the whole folder, so "
                              "give a new or empty folder")
    return target


def _foreign_files(folder: Path) -> list[str]:
    """Names in a non-empty folder without pneumasim's marker or signature files."""
    names = sorted(p.name for p in folder.iterdir())
    if not names or MARKER in names or any(s in names for s in SIGNATURE_FILES):
        return []
    return names


def check_output_file(target: str | Path, inputs=(), option: str = "--out") -> Path:
    """Refuse, before any work, an output file that is a folder, an input, or unwritable."""
    target = Path(target).expanduser()
    if target.is_dir():
        raise OutputError(f"{option} {target}: is a folder; expected a file name")
    for item in inputs:
        if target.exists() and Path(item).exists() and os.path.samefile(target, item) \
                or target.resolve() == Path(item).expanduser().resolve():
            raise OutputError(f"{option} {target}: is the input {item}; writing it would destroy the input")
    if target.exists() and not os.access(target, os.W_OK):
        raise OutputError(f"{option} {target}: the file is read-only")
    check_writable_place(target, option)
    return target


# ---------------------------------------------------------------- swapping

def _renameat2_exchange():
    """libc's renameat2 with RENAME_EXCHANGE (Linux >= 3.15, glibc >= 2.28), or None."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    return fn


_AT_FDCWD, _RENAME_EXCHANGE = -100, 2
_EXCHANGE = _renameat2_exchange()


def swap_in(new: Path, target: Path):
    """Put folder ``new`` at ``target`` in one step; the previous ``target`` is removed.

    Both names always exist or the exchange did not happen: a kill at any moment leaves either
    the previous results or the new ones at ``target``, never neither."""
    if not target.exists():
        os.rename(new, target)
        return
    if _EXCHANGE is not None and _EXCHANGE(_AT_FDCWD, os.fsencode(new), _AT_FDCWD, os.fsencode(target),
                                           _RENAME_EXCHANGE) == 0:
        shutil.rmtree(new, ignore_errors=True)  # now the previous results
        return
    old = target.with_name(f".{target.name}.old-{os.getpid()}")  # no exchange: two renames
    os.rename(target, old)
    os.rename(new, target)
    shutil.rmtree(old, ignore_errors=True)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_abandoned(target: Path):
    """Remove staging folders and files a killed run left beside ``target`` (their process is
    gone), and put back a previous folder a kill between two renames left aside."""
    pattern = re.compile(rf"^\.{re.escape(target.name)}\.(partial|old)-(\d+)")
    for p in target.parent.glob(f".{target.name}.*"):
        m = pattern.match(p.name)
        if not m or _pid_alive(int(m.group(2))):
            continue
        if m.group(1) == "old" and not target.exists():
            os.rename(p, target)
        elif p.is_dir():
            shutil.rmtree(p, ignore_errors=True)
        else:
            p.unlink(missing_ok=True)


#: text outputs that may name their own files (a report's recording paths, a case's truth)
TEXT_SUFFIXES = (".json", ".md", ".txt", ".toml")
_RELOCATE_MAX_BYTES = 50_000_000


def relocate_paths(staging: Path, target: Path):
    """Paths a run wrote into its text outputs name the staging folder; make them name the
    folder the outputs end up in (``.x.partial-<pid>-<random>`` occurs nowhere else)."""
    pairs = [(str(staging), str(target)), (str(staging.resolve()), str(target.resolve()))]
    for f in staging.rglob("*"):
        if f.suffix not in TEXT_SUFFIXES or not f.is_file() or f.stat().st_size > _RELOCATE_MAX_BYTES:
            continue
        try:
            text = f.read_text()
        except (UnicodeDecodeError, OSError):
            continue
        if staging.name not in text:
            continue
        for old, new in pairs:
            text = text.replace(old, new)
        atomic_write_text(f, text)


def _link_tree(src: Path, dst: Path):
    """Hard-link copy of ``src`` into ``dst`` (files are shared until replaced: every writer
    here replaces a file by renaming a new one over it, never writes into it)."""
    for root, dirs, files in os.walk(src):
        rel = Path(root).relative_to(src)
        for d in dirs:
            (dst / rel / d).mkdir(exist_ok=True)
        for f in files:
            if f == MARKER:
                continue
            try:
                os.link(Path(root) / f, dst / rel / f)
            except OSError:
                shutil.copy2(Path(root) / f, dst / rel / f)


# ---------------------------------------------------------------- the folder of a run

class OutputFolder:
    """A run's output folder, written in a staging folder and swapped in whole at the end.

    ``with OutputFolder("runs/x", inputs=[rec]) as out:`` — the target is checked at
    construction (before any work); ``out.path`` is the staging folder to write into;
    ``out.file(p)`` the temporary name of an output ``p`` outside the folder.  Leaving the
    block normally swaps the staging folder in and moves the extra files into place; an
    exception (or Ctrl-C) discards them, and the previous results stay as they were.

    Args:
      target: the folder the results end up in.
      inputs: files the run reads: the target may not hold them (it is replaced whole).
      option: how the user named the target (in messages).
      resumable: keep the staging folder ``.<name>.partial`` when the run fails (it holds the
        per-case files a rerun resumes from); a fresh one starts as a hard-link copy of the
        previous results.
    """

    def __init__(self, target: str | Path, *, inputs=(), option: str = "--out", resumable: bool = False):
        self.target = check_output_folder(target, inputs, option)
        self.option, self.resumable = option, resumable
        self.path: Path | None = None
        self._extra: dict[Path, Path] = {}  # final path -> temporary path

    def __enter__(self) -> "OutputFolder":
        parent = self.target.parent
        try:
            parent.mkdir(parents=True, exist_ok=True)
            remove_abandoned(self.target)
            if self.resumable:
                self.path = parent / f".{self.target.name}.partial"
                if not self.path.is_dir():
                    self.path.mkdir()
                    if self.target.is_dir():
                        _link_tree(self.target, self.path)
            else:
                self.path = Path(tempfile.mkdtemp(dir=parent, prefix=f".{self.target.name}.partial-{os.getpid()}-"))
        except OSError as e:
            raise OutputError(f"{self.option} {self.target}: cannot write beside it in {parent} "
                              f"({e.strerror or e})") from None
        return self

    def file(self, final: str | Path, option: str = "--rerun") -> Path:
        """Where to write output ``final``: inside the staging folder if ``final`` lies in the
        target, else a temporary name beside it, moved into place after the swap."""
        final = Path(final).expanduser()
        if _inside(final.resolve(), self.target.resolve()):
            return self.path / final.resolve().relative_to(self.target.resolve())
        check_output_file(final, option=option)
        final.parent.mkdir(parents=True, exist_ok=True)
        remove_abandoned(final)
        tmp = final.with_name(f".{final.name}.partial-{os.getpid()}{final.suffix}")
        self._extra[final] = tmp
        return tmp

    def commit(self):
        """Swap the staging folder in and move the extra files into place."""
        if not self.resumable:  # a resumable run's case files keep theirs: they identify the cases
            relocate_paths(self.path, self.target)
        (self.path / MARKER).write_text("pneumasim output: replaced whole by the next run into this folder\n")
        os.chmod(self.path / MARKER, file_mode())
        mode = (self.target.stat().st_mode & 0o7777) if self.target.is_dir() else folder_mode()
        os.chmod(self.path, mode)  # mkdtemp's 0700 would hide the results; keep a shared folder's mode
        swap_in(self.path, self.target)
        for final, tmp in self._extra.items():
            if tmp.exists():
                os.replace(tmp, final)

    def discard(self):
        for tmp in self._extra.values():
            tmp.unlink(missing_ok=True)
        if not self.resumable and self.path is not None:
            shutil.rmtree(self.path, ignore_errors=True)

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None and not stop_received():
            self.commit()
            return False
        self.discard()
        raise_if_stopped()  # a stop whose KeyboardInterrupt Python swallowed still stops the run
        return False


class OutputFiles:
    """Single output files (a recording and its sidecar), written to temporary names beside
    their targets and all moved into place at the end; a failure leaves the previous ones."""

    def __init__(self, *targets: str | Path, inputs=(), option: str = "--out"):
        self.targets = [check_output_file(t, inputs, option) for t in targets]
        self.option = option
        self._tmp: dict[Path, Path] = {}

    def __enter__(self) -> "OutputFiles":
        for t in self.targets:
            try:
                t.parent.mkdir(parents=True, exist_ok=True)
            except OSError as e:
                raise OutputError(f"{self.option} {t}: cannot create its folder ({e.strerror or e})") from None
            remove_abandoned(t)
            self._tmp[t] = t.with_name(f".{t.name}.partial-{os.getpid()}{t.suffix}")
        return self

    def file(self, target: str | Path) -> Path:
        return self._tmp[Path(target).expanduser()]

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None and not stop_received():  # in reverse: the recording (opened first) moves last
            for t in self.targets[::-1]:
                if self._tmp[t].exists():
                    os.chmod(self._tmp[t], file_mode())
                    os.replace(self._tmp[t], t)
        for tmp in self._tmp.values():
            tmp.unlink(missing_ok=True)
        raise_if_stopped()  # a stop whose KeyboardInterrupt Python swallowed still stops the run
        return False
