"""Files written whole and files read safely.

:func:`write_atomic` writes a temporary file in a private folder beside the target and renames it over, and
removes the temporary file on any error, so that a reader, a crash or a full disk never leaves half a file or a
stray temporary one behind. :func:`create_new` and :func:`open_new` create a file that is new in its folder
(``O_EXCL | O_NOFOLLOW``): a symbolic link planted where a run's log goes is refused, never followed, and a file
left there earlier is unlinked, never truncated (a hard link's other names keep their content).

:func:`open_regular` and :func:`read_regular` open a file given by a user only when it is a regular file, opened
without blocking: a FIFO, a device (``/dev/zero``) or a socket is refused at once instead of waited on or read
without end, and :func:`read_regular` refuses a file over its size limit before reading it.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import stat
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, BinaryIO

_CLOEXEC = getattr(os, "O_CLOEXEC", 0)
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


class NotRegularFile(OSError):
    """A path that is not a regular file (a FIFO, a device, a socket, a folder), or a symbolic link where a new
    file was to be created; ``strerror`` says which, in words."""


class TooLarge(OSError):
    """A file over the size limit its reader accepts."""


def write_atomic(path: Path, write: Callable[[Path], Any], mode: int = 0o666) -> None:
    """``write(tmp)`` into a new file ``tmp`` (named as ``path``: a writer may infer the format from its suffix)
    in a private folder (mode 0700) made beside ``path``, then renamed over ``path``; on any error the temporary
    folder is removed and the error propagates (``path`` is then as it was). Nobody else can put a link where
    ``tmp`` is, and the rename replaces ``path`` itself: a symbolic link at ``path`` is replaced, never
    followed. ``mode``: the new file's, less the umask (``0o600`` for a file of passwords)."""
    private = Path(tempfile.mkdtemp(prefix=f".{path.stem}.tmp", dir=path.parent))
    try:
        tmp = private / path.name
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW | _CLOEXEC, mode))
        write(tmp)
        os.replace(tmp, path)
    finally:
        shutil.rmtree(private, ignore_errors=True)


def create_new(path: Path, mode: int = 0o644) -> int:
    """A file descriptor, open for writing, of a file created new at ``path`` (``O_CREAT | O_EXCL |
    O_NOFOLLOW``). A regular file already there (an earlier attempt's) is unlinked first, never truncated; a
    symbolic link or anything else there is refused (:class:`NotRegularFile`), never followed."""
    for _ in range(3):
        try:
            return os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW | _CLOEXEC, mode)
        except FileExistsError:
            st = os.lstat(path)
            if not stat.S_ISREG(st.st_mode):
                kind = "a symbolic link" if stat.S_ISLNK(st.st_mode) else "not a regular file"
                raise NotRegularFile(errno.EEXIST, f"{path.name} is {kind}: not followed nor replaced") from None
            with contextlib.suppress(FileNotFoundError):
                os.unlink(path)
    raise NotRegularFile(errno.EEXIST, f"{path.name} keeps being created by another process")


def open_new(path: Path) -> BinaryIO:
    """:func:`create_new` as a binary file object."""
    return os.fdopen(create_new(path), "wb")


def open_regular(path: Path | str) -> BinaryIO:
    """``path`` open for reading when it is a regular file (or a symbolic link to one the user named): opened
    without blocking and checked on the open descriptor, so that a FIFO, a device or a socket is refused at
    once (:class:`NotRegularFile`), never waited on."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | _CLOEXEC)
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            kind = ("a folder" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode)
                    else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "a socket")
            raise NotRegularFile(errno.EINVAL, f"not a regular file ({kind})")
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_regular(path: Path | str, limit: int) -> bytes:
    """The bytes of the regular file ``path`` (:func:`open_regular`); :class:`TooLarge` when it holds more than
    ``limit`` bytes, told from its size before it is read (and never more than ``limit + 1`` bytes read, should
    it grow meanwhile)."""
    with open_regular(path) as f:
        if os.fstat(f.fileno()).st_size > limit:
            raise TooLarge(errno.EFBIG, f"larger than {_size(limit)}")
        data = f.read(limit + 1)
    if len(data) > limit:
        raise TooLarge(errno.EFBIG, f"larger than {_size(limit)}")
    return data


def _size(n: int) -> str:
    return f"{n >> 20} MiB" if n >= 1 << 20 else f"{n >> 10} KiB" if n >= 1 << 10 else f"{n} bytes"


def write_json(path: Path, obj: Any) -> None:
    """JSON (indented) to ``path``, atomically."""
    data = json.dumps(obj, indent=2)
    write_atomic(path, lambda tmp: tmp.write_text(data))
