"""Writing files so that nothing already written is lost.

Every file robofleet writes goes through this module:

* :func:`replacing` (and :func:`write_text`, :func:`write_bytes` on top of it) writes one
  file: the writer fills a hidden temporary file in the target's directory
  (``.<name>.tmp-<pid>-<hex><suffix>``, the suffix kept so that writers choosing a format
  by suffix keep working), which is flushed to disk and renamed over the target with
  :func:`os.replace` (atomic on POSIX and Windows), and the directory is synced.
* :func:`staged_files` replaces a *set* of files of a directory together (a trace's two
  files, a run's trace and summary): they are written into a hidden staging directory
  inside it, and moved in only once all are complete, the files they replace set aside
  first and put back if a move fails.

Why nothing is lost: until the final rename a target is untouched, and a rename within a
directory is atomic, so a writer stopped at any moment (Ctrl-C, an error, a full disk,
a crash) leaves each file either as it was or complete, plus at most a hidden temporary
that readers ignore (removed unless the process is killed outright). A set is swapped by
renames run under :func:`deferred_interrupts`, so Ctrl-C cannot stop them halfway (it
takes effect, as ``KeyboardInterrupt``, right after the set is in place), and an error
during them puts the earlier files back; only a crash of the whole process during those
few renames can leave part of the earlier set in the hidden staging directory.
"""

from __future__ import annotations

import os
import shutil
import signal
import threading
import uuid
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

TEMPORARY_MARK = ".tmp-"
"""Part of the name of every temporary file or staging directory (which also starts with ``.``)."""
SET_ASIDE = ".replaced"
"""The folder of a staging directory holding the files a set replaces, until it is in place."""


def temporary_name(path: str | Path) -> Path:
    """A fresh hidden name next to ``path`` for the file being written (same suffix)."""
    path = Path(path)
    return path.with_name(f".{path.name}{TEMPORARY_MARK}{os.getpid()}-{uuid.uuid4().hex[:8]}{path.suffix}")


def is_temporary(path: str | Path) -> bool:
    """Whether ``path`` names a file or folder being written (see :func:`temporary_name`)."""
    name = Path(path).name
    return name.startswith(".") and TEMPORARY_MARK in name


@contextmanager
def replacing(path: str | Path) -> Iterator[Path]:
    """Yield the temporary path to write ``path``'s new content to; when the block ends
    without an exception, that file becomes ``path`` (synced, then renamed over it).

    On any exception, ``KeyboardInterrupt`` included, the temporary is removed and
    ``path`` is left as it was. Parent folders are created.

    Example
    -------
    >>> with replacing(folder / "figure.png") as temp:   # doctest: +SKIP
    ...     fig.savefig(temp)
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temp = temporary_name(path)
    try:
        yield temp
        sync_file(temp)
        os.replace(temp, path)
        sync_directory(path.parent)
    finally:
        temp.unlink(missing_ok=True)


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through :func:`replacing`; return the path."""
    with replacing(path) as temp:
        temp.write_text(text, encoding="utf-8")
    return Path(path)


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through :func:`replacing`; return the path."""
    with replacing(path) as temp:
        temp.write_bytes(data)
    return Path(path)


@dataclass
class Staging:
    """A set of files being written: into :attr:`path`; :attr:`moved` once they are in place."""

    path: Path
    moved: bool = False


@contextmanager
def staged_files(directory: str | Path, replaced: Iterable[str] = ()) -> Iterator[Staging]:
    """Yield a :class:`Staging` whose empty ``path`` the files are written into; when the
    block ends without an exception, they are moved into ``directory`` together, and the
    files named in ``replaced`` that ``directory`` held (an earlier run's) are removed.

    Until the block ends ``directory`` is untouched; on any exception (``KeyboardInterrupt``
    included) the staging directory is removed, and so are the folders this call created.
    The moves run with Ctrl-C deferred (:func:`deferred_interrupts`: a Ctrl-C during them
    is raised once they are done, with ``moved`` set); the files they replace are first set
    aside in the staging directory and moved back if a move fails, so ``directory`` ends
    with either all the old files or all the new ones. Files of ``directory`` not named in
    ``replaced`` and not written anew are kept.
    """
    directory = Path(directory)
    created = missing_folders(directory)
    directory.mkdir(parents=True, exist_ok=True)
    staging = Staging(directory / f".staged{TEMPORARY_MARK}{os.getpid()}-{uuid.uuid4().hex[:8]}")
    try:
        staging.path.mkdir()
        yield staging
        with deferred_interrupts():
            move_in(staging.path, directory, set(replaced))
            staging.moved = True
    except BaseException:
        if not staging.moved:
            remove_created(staging.path, created)
        raise
    finally:
        shutil.rmtree(staging.path, ignore_errors=True)


def remove_created(stage: Path, created: list[Path]) -> None:
    """Remove the staging directory and the folders created for it (those still empty)."""
    shutil.rmtree(stage, ignore_errors=True)
    for folder in reversed(created):
        try:
            folder.rmdir()
        except OSError:
            break


def move_in(stage: Path, directory: Path, replaced: set[str]) -> None:
    """Move the files of ``stage`` into ``directory``, setting aside the ``replaced`` ones
    first; on failure, undo the moves made so far (see :func:`staged_files`)."""
    new = sorted(p.name for p in stage.iterdir())
    for name in new:
        if (stage / name).is_file():
            sync_file(stage / name)
    aside = stage / SET_ASIDE
    aside.mkdir()
    set_aside: list[str] = []
    moved: list[str] = []
    try:
        for name in sorted(replaced | set(new)):
            if (directory / name).is_file() or (directory / name).is_symlink():
                os.replace(directory / name, aside / name)
                set_aside.append(name)
        for name in new:
            os.replace(stage / name, directory / name)
            moved.append(name)
        sync_directory(directory)
    except BaseException:
        for name in reversed(moved):
            os.replace(directory / name, stage / name)
        for name in set_aside:
            os.replace(aside / name, directory / name)
        raise


def missing_folders(directory: Path) -> list[Path]:
    """The folders of ``directory``'s path that do not exist yet, outermost first."""
    missing = []
    for folder in (directory, *directory.parents):
        if folder.exists():
            break
        missing.append(folder)
    return missing[::-1]


@contextmanager
def deferred_interrupts() -> Iterator[None]:
    """Hold Ctrl-C (SIGINT) back for the duration of the block and deliver it after.

    In the main thread only (the one Python delivers signals to), and while the handler
    in place is a Python one; otherwise the block runs unchanged. A SIGINT received
    during the block is handed to the handler that was in place before (by default:
    ``KeyboardInterrupt`` raised when the block ends).
    """
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) is None:
        yield  # no Python handler to put back (one installed from C): leave signals alone
        return
    received: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if received:
            if callable(previous):
                previous(signal.SIGINT, None)
            elif previous == signal.SIG_DFL:
                signal.raise_signal(signal.SIGINT)


def sync_file(path: Path) -> None:
    """Flush ``path``'s content to disk (so the rename that follows never exposes an empty file)."""
    with open(path, "rb") as handle:
        os.fsync(handle.fileno())


def sync_directory(directory: Path) -> None:
    """fsync a directory so a rename in it survives a crash (a no-op where unsupported)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
