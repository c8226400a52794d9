"""Downloading a registry map into the cache: every file to a temporary folder beside the cache, each checked
against its sha256, and the folder renamed into place only when all are good, so that a failed fetch (an
unreachable source, a checksum mismatch, Ctrl-C) leaves nothing in the cache.

The files come from their pinned upstream addresses, or from a mirror laid out as ``MIRROR/<map
name>/<upstream file name>``: a folder (for a machine without the internet) or a base URL (``http://`` or
``https://``). The cache itself has that layout, so one machine's cache can serve as another's mirror.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import os
import shutil
import tempfile
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path
from typing import BinaryIO

from fleet_emu.core.errors import MapError
from fleet_emu.world.registry import MapFile, RegistryMap, cache_dir, lookup, verified

#: Seconds to wait for a server; the largest map file is under 2 MB.
TIMEOUT = 30.0
#: A file larger than this is refused while it downloads (the largest registry file is 1.7 MB).
MAX_BYTES = 64 << 20


@dataclasses.dataclass(frozen=True)
class Fetched:
    """What a fetch did: the map's folder in the cache, where its files came from, and whether they were
    already there (nothing downloaded)."""

    entry: RegistryMap
    folder: Path
    origins: tuple[str, ...]
    cached: bool


def origin(entry: RegistryMap, f: MapFile, mirror: str | None) -> str:
    """Where ``f`` is read from: its upstream URL, or the mirror's ``<name>/<file name>`` (a URL or a path)."""
    if mirror is None:
        return entry.url(f)
    if _is_url(mirror):
        return f"{mirror.rstrip('/')}/{urllib.parse.quote(entry.name)}/{urllib.parse.quote(f.name)}"
    return str(Path(mirror).expanduser() / entry.name / f.name)


def _is_url(text: str) -> bool:
    return text.startswith(("http://", "https://"))


def fetch(entry: RegistryMap, mirror: str | None = None, *, force: bool = False) -> Fetched:
    """Put ``entry``'s files in the cache (a map already there and intact is kept, unless ``force``); a
    one-line MapError when a source cannot be read or a file's sha256 differs, with nothing left behind."""
    root = cache_dir()
    folder = root / entry.name
    origins = tuple(origin(entry, f, mirror) for f in entry.files)
    if not force and verified(entry, folder):
        return Fetched(entry, folder, origins, cached=True)
    made = _missing_ancestors(root)
    try:
        root.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{entry.name}.", suffix=".part", dir=root))
    except OSError as exc:
        raise MapError(f"map {entry.name}: cannot write to the cache {root} ({exc.strerror or exc})") from None
    hint = "; without the internet, use --mirror DIR|URL" if mirror is None else ""
    try:
        for f, where in zip(entry.files, origins, strict=True):
            _download(entry, f, where, tmp / f.name, hint)
        _install(entry, tmp, folder)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        for d in made:  # the folders this fetch made, deepest first, when it left nothing in them
            _remove_if_empty(d)
    return Fetched(entry, folder, origins, cached=False)


def _missing_ancestors(path: Path) -> list[Path]:
    """``path`` and its ancestors that do not exist yet, deepest first."""
    out = []
    while not path.exists() and path != path.parent:
        out.append(path)
        path = path.parent
    return out


def _download(entry: RegistryMap, f: MapFile, where: str, dest: Path, hint: str) -> None:
    """Copy ``where`` into ``dest``, hashing on the way; MapError on a read error, an oversize file or a
    sha256 that is not the registry's."""
    h = hashlib.sha256()
    size = 0
    try:
        with _open(where) as src, dest.open("wb") as out:
            for block in iter(lambda: src.read(1 << 16), b""):
                size += len(block)
                if size > MAX_BYTES:
                    raise MapError(f"map {entry.name}: {where} is larger than {MAX_BYTES >> 20} MB; nothing was "
                                   "kept")
                h.update(block)
                out.write(block)
    except MapError:
        raise
    except (OSError, ValueError, urllib.error.URLError) as exc:  # HTTPError, timeouts and refusals are OSErrors
        raise MapError(f"map {entry.name}: cannot read {where} ({_reason(exc)}); nothing was kept{hint}") \
            from None
    if h.hexdigest() != f.sha256:
        raise MapError(f"map {entry.name}: {f.name} from {where} has sha256 {h.hexdigest()[:16]}..., not the "
                       f"registry's {f.sha256[:16]}...; nothing was kept")


class _open:
    """A readable binary stream of a path or an http(s) URL (a context manager)."""

    def __init__(self, where: str) -> None:
        self.where = where
        self.stream: BinaryIO | None = None

    def __enter__(self) -> BinaryIO:
        if _is_url(self.where):
            self.stream = urllib.request.urlopen(self.where, timeout=TIMEOUT)  # http(s) only (_is_url)
        else:
            self.stream = Path(self.where).open("rb")
        return self.stream

    def __exit__(self, *exc: object) -> None:
        if self.stream is not None:
            self.stream.close()


def _reason(exc: BaseException) -> str:
    if isinstance(exc, urllib.error.HTTPError):
        return f"HTTP {exc.code} {exc.reason}"
    if isinstance(exc, urllib.error.URLError):
        return str(exc.reason)
    if isinstance(exc, FileNotFoundError):
        return "no such file"
    return getattr(exc, "strerror", None) or str(exc) or type(exc).__name__


def _install(entry: RegistryMap, tmp: Path, folder: Path) -> None:
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
            raise MapError(f"map {entry.name}: cannot move it into the cache {folder} ({exc.strerror or exc})") \
                from None


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
