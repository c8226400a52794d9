"""Downloading a registry map (or a radio site, ``world/sites.py``: any :class:`~fleet_emu.world.registry.Pinned`
entry) into the cache: every file to a temporary folder beside the cache, each checked
against its sha256, and the folder renamed into place only when all are good, so that a failed fetch (an
unreachable source, a checksum mismatch, Ctrl-C) leaves nothing in the cache.

The files come from their pinned upstream addresses, or from a mirror laid out as ``MIRROR/<map
name>/<upstream file name>``: a folder (for a machine without the internet) or a base URL (``http://`` or
``https://``). The cache itself has that layout, so one machine's cache can serve as another's mirror.

Nothing can hold a fetch: each file must arrive whole within :data:`DEADLINE` seconds (a server that sends a
byte now and then is cut off then, not only one silent for :data:`TIMEOUT`), a mirror folder's files are read
only when regular (a symlink to one included: a FIFO or a device is refused, never waited on), and SIGINT or
SIGTERM during a fetch remove its temporary folder (the caller turns SIGTERM into an exception:
``launch/maps_cli.py``, ``launch/radio_cli.py``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import os
import shutil
import signal
import stat
import tempfile
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

from fleet_emu.core.errors import MapError
from fleet_emu.world.registry import MapFile, Pinned, RegistryMap, cache_dir, lookup, verified

#: Seconds to wait for a server to connect or send anything; the largest map file is under 2 MB.
TIMEOUT = 30.0
#: Seconds for the whole of one file, connection included, however the server sends it.
DEADLINE = 120.0
_SIGNALS = {signal.SIGINT, signal.SIGTERM}
#: A file larger than this is refused while it downloads (the largest registry file is 1.7 MB).
MAX_BYTES = 64 << 20


@dataclasses.dataclass(frozen=True)
class Fetched:
    """What a fetch did: the map's folder in the cache, where its files came from, and whether they were
    already there (nothing downloaded)."""

    entry: Pinned
    folder: Path
    origins: tuple[str, ...]
    cached: bool


def origin(entry: Pinned, f: MapFile, mirror: str | None) -> str:
    """Where ``f`` is read from: its upstream URL, or the mirror's ``<name>/<file name>`` (a URL or a path)."""
    if mirror is None:
        return entry.url(f)
    if _is_url(mirror):
        return f"{mirror.rstrip('/')}/{urllib.parse.quote(entry.name)}/{urllib.parse.quote(f.name)}"
    return str(Path(mirror).expanduser() / entry.name / f.name)


def _is_url(text: str) -> bool:
    return text.startswith(("http://", "https://"))


def fetch(entry: Pinned, mirror: str | None = None, *, force: bool = False) -> Fetched:
    """Put ``entry``'s files in the cache (a map already there and intact is kept, unless ``force``); a
    one-line MapError when a source cannot be read or a file's sha256 differs, with nothing left behind."""
    root = cache_dir(entry.cache)
    folder = root / entry.name
    origins = tuple(origin(entry, f, mirror) for f in entry.files)
    if not force and verified(entry, folder):
        return Fetched(entry, folder, origins, cached=True)
    made = _missing_ancestors(root)
    with _signals_held():  # a signal between making the folder and owning it would leave it behind
        try:
            root.mkdir(parents=True, exist_ok=True)
            tmp = Path(tempfile.mkdtemp(prefix=f".{entry.name}.", suffix=".part", dir=root))
        except OSError as exc:
            raise MapError(f"{entry.kind} {entry.name}: cannot write to the cache {root} "
                           f"({exc.strerror or exc})") from None
    hint = "; without the internet, use --mirror DIR|URL" if mirror is None else ""
    try:
        for f, where in zip(entry.files, origins, strict=True):
            _download(entry, f, where, tmp / f.name, hint)
        _install(entry, tmp, folder)
    finally:
        with _signals_held():  # a second Ctrl-C does not cut the clean-up short
            shutil.rmtree(tmp, ignore_errors=True)
            for d in made:  # the folders this fetch made, deepest first, when it left nothing in them
                _remove_if_empty(d)
    return Fetched(entry, folder, origins, cached=False)


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM held back (delivered on leaving) for a few file operations that must not be cut."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _missing_ancestors(path: Path) -> list[Path]:
    """``path`` and its ancestors that do not exist yet, deepest first."""
    out = []
    while not path.exists() and path != path.parent:
        out.append(path)
        path = path.parent
    return out


def _download(entry: Pinned, f: MapFile, where: str, dest: Path, hint: str) -> None:
    """Copy ``where`` into ``dest``, hashing on the way; MapError on a read error, an oversize file or a
    sha256 that is not the registry's."""
    h = hashlib.sha256()
    size = 0
    try:
        with _open(where) as src, dest.open("wb") as out:
            for block in iter(src.read, b""):
                size += len(block)
                if size > MAX_BYTES:
                    raise MapError(f"{entry.kind} {entry.name}: {where} is larger than {MAX_BYTES >> 20} MB; "
                                   "nothing was kept")
                h.update(block)
                out.write(block)
    except MapError:
        raise
    except (OSError, ValueError, urllib.error.URLError) as exc:  # HTTPError, timeouts and refusals are OSErrors
        raise MapError(f"{entry.kind} {entry.name}: cannot read {where} ({_reason(exc)}); nothing was kept{hint}") \
            from None
    if h.hexdigest() != f.sha256:
        raise MapError(f"{entry.kind} {entry.name}: {f.name} from {where} has sha256 {h.hexdigest()[:16]}..., not the "
                       f"registry's {f.sha256[:16]}...; nothing was kept")


class _open:
    """The blocks of a path or an http(s) URL (a context manager: ``read()`` gives the next block, ``b""`` at
    the end); an OSError once :data:`DEADLINE` has passed, or for a path that is not a regular file."""

    def __init__(self, where: str) -> None:
        self.where = where
        self.stream: Any = None
        self.deadline = time.monotonic() + DEADLINE

    def __enter__(self) -> _open:
        if _is_url(self.where):  # http(s) only (_is_url)
            self.stream = urllib.request.urlopen(self.where, timeout=self._left())
        else:
            self.stream = _regular(Path(self.where))
        return self

    def _left(self) -> float:
        """Seconds the next wait may take; TimeoutError once the deadline has passed (or all but passed)."""
        left = self.deadline - time.monotonic()
        if left <= 0.01:
            raise TimeoutError(f"not whole within {DEADLINE:g} s")
        return min(TIMEOUT, left)

    def read(self) -> bytes:
        if not _is_url(self.where):
            return bytes(self.stream.read(1 << 16))
        sock = getattr(getattr(getattr(self.stream, "fp", None), "raw", None), "_sock", None)
        if sock is not None:
            sock.settimeout(self._left())  # each wait on the server ends by the deadline
        try:
            block = bytes(self.stream.read1(1 << 16))  # whatever came: a trickle cannot hold one read open
        except TimeoutError:
            self._left()  # the deadline's own error, when that is what ended the wait
            raise
        self._left()
        return block

    def __exit__(self, *exc: object) -> None:
        if self.stream is not None:
            self.stream.close()


def _regular(path: Path) -> BinaryIO:
    """``path`` open for reading when it is a regular file (or a symlink to one): opened without blocking, so
    a FIFO or a device in a mirror folder is refused at once, never waited on."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise OSError(f"{path.name} is not a regular file")
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def _reason(exc: BaseException) -> str:
    if isinstance(exc, urllib.error.HTTPError):
        return f"HTTP {exc.code} {exc.reason}"
    if isinstance(exc, urllib.error.URLError):
        return str(exc.reason)
    if isinstance(exc, FileNotFoundError):
        return "no such file"
    return getattr(exc, "strerror", None) or str(exc) or type(exc).__name__


def _install(entry: Pinned, tmp: Path, folder: Path) -> None:
    """Rename the checked temporary folder into place (a stale or altered copy is replaced); when another
    fetch got there first with the same files, its copy stands."""
    if folder.exists():
        if verified(entry, folder):
            return
        shutil.rmtree(folder)
    try:
        os.rename(tmp, folder)
    except OSError as exc:
        if not verified(entry, folder):
            raise MapError(f"{entry.kind} {entry.name}: cannot move it into the cache {folder} "
                           f"({exc.strerror or exc})") from None


def _remove_if_empty(path: Path) -> None:
    with contextlib.suppress(OSError):
        path.rmdir()


def entries_in(names: list[str]) -> list[RegistryMap]:
    """The registry maps of ``names`` (each once, in order); a MapError on the first unknown name, before any
    download."""
    seen: dict[str, RegistryMap] = {}
    for name in names:
        seen.setdefault(name, lookup(name))
    return list(seen.values())
