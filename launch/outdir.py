"""A run's output folder, guarded: one run owns it, and what it writes is whole.

:func:`claim` takes an exclusive ``flock`` on the folder's lock file (:data:`LOCK`, holding the owner's pid)
before anything is written there and keeps it to the last write: a second run (or ``fleet recover``, or
``fleet report``) into a folder another process holds is refused naming that pid. A folder that already holds a
run (:data:`RUN_MARKERS`) is refused too, unless ``overwrite``, which first removes every file that run left
(:func:`run_files`: its logs, plots and metrics as well). Every file goes through :func:`write_atomic`: a
temporary file beside it and a rename, the temporary file removed on any error, so a reader, a crash or a full
disk never leaves half a file or a stray temporary one; every other file (the processes' logs, the recording) is
created new (:func:`~fleet_emu.core.files.create_new`). A folder holding a symbolic link to a file (where a run
file goes: ``r0.log``, ``.fleet.lock``...) is refused in one line (:func:`refuse_links`), never followed.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import re
import shutil
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path

from fleet_emu.core.errors import ConfigError, RunError
from fleet_emu.core.files import write_atomic, write_json
from fleet_emu.core.setting_names import option

__all__ = ["DiskFault", "FolderLock", "claim", "claimed", "disk_fault", "lock_folder", "make_folder", "refuse_held",
           "refuse_links", "run_files",
           "write_atomic", "write_json"]

LOCK = ".fleet.lock"
#: Files whose presence means the folder holds a run.
RUN_MARKERS = ("result.json", "run.mcap", "scenario.json", "run.mcap.cut")
#: Every file a run (and ``fleet report`` on it) writes in its folder: removed by ``--overwrite``.
_RUN_FILE = re.compile(r"(result\.json|scenario\.json|map\.npz|run\.mcap(\.cut)?|metrics\.json|[\w.-]+\.png|"
                       r"[\w.-]+\.log|\.[\w.-]*\.tmp[\w.-]*|ros2\.users)")  # ros2.users: `fleet run --ros2`


class DiskFault(RunError):
    """A write of the run's files failed (a full disk, a quota, a folder removed under the run): the run
    ends at once, its processes stopped, and this one line is told."""


def disk_fault(folder: Path, exc: OSError, what: str = "") -> DiskFault:
    """The one line for a failed write in ``folder``."""
    name = f" ({what})" if what else ""
    return DiskFault(f"cannot write the run's files in {folder}{name}: {exc.strerror or exc}")


class FolderLock:
    """The exclusive lock on a folder, held while the process writes there; :meth:`release` ends it and removes
    the lock file."""

    def __init__(self, folder: Path, fd: int) -> None:
        self.folder, self._fd = folder, fd

    def release(self) -> None:
        if self._fd < 0:
            return
        with contextlib.suppress(OSError):
            (self.folder / LOCK).unlink()  # before the unlock: a process waiting on this file sees it gone
        os.close(self._fd)
        self._fd = -1


def lock_folder(folder: Path, flag: str = "--out") -> FolderLock:
    """The exclusive lock on ``folder`` (which exists), this process's pid written in its lock file; a
    ConfigError naming the pid of the process that holds it. Safe against a lock file removed by its previous
    owner meanwhile: the lock is taken again on the file now at the path."""
    path = folder / LOCK
    refuse_links(folder, flag)
    for _ in range(10):
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW, 0o644)
        except OSError as exc:
            if exc.errno == errno.ELOOP:  # a link planted there since refuse_links looked
                raise _link_refusal(folder, flag, [LOCK]) from None
            raise ConfigError(f"{flag} {folder}: cannot write there ({exc.strerror or exc})") from None
        if os.fstat(fd).st_nlink != 1 or not stat.S_ISREG(os.fstat(fd).st_mode):  # a hard link: never truncated
            os.close(fd)
            raise _link_refusal(folder, flag, [LOCK])
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise ConfigError(f"{flag} {folder}: cannot lock it ({exc.strerror or exc})") from None
            raise ConfigError(f"{flag} {folder} is in use by another run (pid {_holder(path)}): wait for it to end, "
                              f"or choose another folder") from None
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if not same:  # the previous owner removed the file between our open and our lock: take the new one
            os.close(fd)
            continue
        try:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
        except OSError as exc:
            os.close(fd)
            with contextlib.suppress(OSError):
                path.unlink()
            raise ConfigError(f"{flag} {folder}: cannot write there ({exc.strerror or exc})") from None
        return FolderLock(folder, fd)
    raise ConfigError(f"{flag} {folder}: its lock file keeps changing (another run is starting there)")


def refuse_links(folder: Path, flag: str = "--out") -> None:
    """A ConfigError of one line when ``folder`` holds a symbolic link that is not to a folder (a run's files
    are never symbolic links: one where ``r0.log``, ``result.json`` or ``.fleet.lock`` goes would have a run
    overwrite its target), naming them."""
    links = []
    with contextlib.suppress(OSError):
        for entry in os.scandir(folder):
            if entry.is_symlink() and not entry.is_dir(follow_symlinks=True):
                links.append(entry.name)
    if links:
        raise _link_refusal(folder, flag, sorted(links))


def _link_refusal(folder: Path, flag: str, names: list[str]) -> ConfigError:
    shown = ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")
    return ConfigError(f"{flag} {folder} holds symbolic links where a run's files go ({shown}): a run never "
                       f"follows them; remove them or choose another folder")


def _holder(path: Path) -> str:
    """The pid written in a lock file (``unknown`` while its owner has not written it yet)."""
    with contextlib.suppress(OSError, ValueError):
        return str(int(path.read_text().split()[0]))
    return "unknown"


def held_run(folder: Path) -> list[str]:
    """The files of :data:`RUN_MARKERS` in ``folder``."""
    return [name for name in RUN_MARKERS if (folder / name).exists()]


def refuse_held(out: Path, overwrite: bool) -> None:
    """A ConfigError when ``out`` holds a run and ``overwrite`` is not given (nothing when it does not exist)."""
    found = held_run(out) if out.is_dir() else []
    if found and not overwrite:
        raise ConfigError(f"{option('out')} {out} holds a run ({', '.join(found)}): pass "
                          f"{option('overwrite', 'True')} to replace it, "
                          f"or choose another folder")


def run_files(folder: Path) -> list[Path]:
    """Every file a run left in ``folder`` (not subfolders, nor files of other tools)."""
    return sorted(p for p in folder.iterdir() if p.name != LOCK and _RUN_FILE.fullmatch(p.name) and not p.is_dir())


def make_folder(out: Path, flag: str = "--out") -> None:
    """Create ``out`` (and its missing parents) and check it is writable; a ConfigError, and no directory left
    behind, when it cannot be written."""
    out = out.absolute()
    top = next((p for p in (*reversed(out.parents), out) if not p.exists()), None)
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        if top is not None:
            shutil.rmtree(top, ignore_errors=True)
        raise ConfigError(f"{flag} {out}: cannot write there ({exc.strerror or exc})") from None


def claim(out: Path, overwrite: bool = False) -> FolderLock:
    """Create ``out``, lock it, and make it empty of any earlier run: refused (ConfigError, exit 2) when another
    process holds it, or when it holds a run and ``overwrite`` is not given; with ``overwrite`` that run's files
    are removed first."""
    make_folder(out)
    lock = lock_folder(out)
    try:
        refuse_held(out, overwrite)
        if overwrite:
            for path in run_files(out):
                path.unlink()
    except OSError as exc:
        lock.release()
        raise ConfigError(f"{option('out')} {out}: cannot remove the earlier run's files "
                          f"({exc.strerror or exc})") from None
    except BaseException:
        lock.release()
        raise
    return lock


@contextlib.contextmanager
def claimed(out: Path | None, overwrite: bool = False) -> Iterator[None]:
    """:func:`claim` for the ``with`` block (nothing when ``out`` is None)."""
    lock = claim(out, overwrite) if out is not None else None
    try:
        yield
    finally:
        if lock is not None:
            lock.release()
