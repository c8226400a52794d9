"""Measured radio sites: the registry of public ones (``sites.toml`` beside this module), fetched like maps
(:mod:`fleet_emu.world.fetch`, into ``<user cache>/radio/<name>/``), and a site's three files read into arrays.

A site is three CSV files (docs/guides/radio-measured.md): the anchors (``id,x,y,z`` in metres, the fixed
receivers), the walls (``x,y``, the vertices of one closed polyline around the free space) and the readings
(``x,y`` of the transmitter, optionally ``z`` its height, and ``rssi_<id>`` in dBm heard by each anchor, empty
where it heard nothing). A registry site is named; a user's own is a folder holding ``anchors.csv``,
``layout.csv`` and ``readings.csv``. Every file is checked before anything is computed on it: a missing column,
a position that is not a finite number, or an anchor outside the walls' box is one line.
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import io
import math
import os
import stat
import tomllib
from pathlib import Path, PurePosixPath
from typing import ClassVar

import numpy as np

from fleet_emu.core.errors import ConfigError
from fleet_emu.world.registry import MapFile, Upstream, cache_dir, verified

SITES_FILE = Path(__file__).resolve().parent / "sites.toml"
#: The three files of a site given as a folder.
FOLDER_FILES = ("anchors.csv", "layout.csv", "readings.csv")
#: A site file larger than this is refused before it is read (the largest registry file is 0.7 MB), and so is
#: one of more rows than :data:`MAX_ROWS` (every reading's walls are counted, one call per anchor).
MAX_BYTES = 64 << 20
MAX_ROWS = 200_000


@dataclasses.dataclass(frozen=True)
class RadioSite(Upstream):
    """A public measured site: where it comes from (``repo`` at ``commit``), its licence and citation, its three
    files (anchors, layout, readings, in that order) and the transmitter's height when the readings give none."""

    name: str
    description: str
    repo: str
    commit: str
    licence: str
    citation: str
    files: tuple[MapFile, ...]
    tag_height: float
    kind: ClassVar[str] = "radio site"
    cache: ClassVar[str] = "radio"


@functools.cache
def sites() -> dict[str, RadioSite]:
    """Every registry site by name, in the file's order."""
    raw = tomllib.loads(SITES_FILE.read_text())
    out = {}
    for name, s in raw["sites"].items():
        src = raw["sources"][s["source"]]
        files = tuple(MapFile(s[k]["path"], s[k]["sha256"]) for k in ("anchors", "layout", "readings"))
        out[name] = RadioSite(name=name, description=s["description"], repo=src["repo"], commit=src["commit"],
                              licence=src["licence"], citation=s["citation"], files=files,
                              tag_height=float(s["tag_height"]))
    return out


def lookup_site(name: str) -> RadioSite:
    """The registry site ``name``; a one-line ConfigError naming the known ones otherwise."""
    try:
        return sites()[name]
    except KeyError:
        raise ConfigError(f"unknown radio site {name!r} (the registry has: {', '.join(sites())}; `fleet radio "
                          "sites` lists them; a folder of your own needs a path with a '/')") from None


def fetch_command(name: str) -> str:
    return f"fleet radio fetch {name}"


def is_fetched(name: str) -> bool:
    """Whether the site is in the cache, every file intact."""
    return verified(lookup_site(name), cache_dir("radio") / name)


@dataclasses.dataclass(frozen=True)
class Site:
    """A site's measurements as arrays: ``anchor_ids`` (N), ``anchors`` (N x 3, metres), ``layout`` (M x 2, the
    closed wall polyline), the readings' transmitter positions ``xy`` (K x 2) and heights ``z`` (K), and
    ``rss`` (K x N, dBm, NaN where an anchor heard nothing)."""

    name: str
    anchor_ids: tuple[int, ...]
    anchors: np.ndarray
    layout: np.ndarray
    xy: np.ndarray
    z: np.ndarray
    rss: np.ndarray

    @property
    def readings(self) -> int:
        """The number of (position, anchor) readings: the RSS values that are not missing."""
        return int(np.isfinite(self.rss).sum())


def site_files(spec: str) -> tuple[str, tuple[Path, Path, Path], float | None]:
    """The name, the three files (anchors, layout, readings) and the registry's tag height (None for a folder)
    of ``spec``: a registry name (fetched and intact, else a one-line error naming the command that fetches it)
    or a folder holding :data:`FOLDER_FILES`."""
    if "/" not in spec and not Path(spec).is_dir():
        entry = lookup_site(spec)
        folder = cache_dir("radio") / spec
        if not verified(entry, folder):
            state = "is not fetched" if not folder.exists() else "is incomplete or altered in the cache"
            raise ConfigError(f"radio site {spec} {state}: run `{fetch_command(spec)}` (it downloads "
                              f"{entry.source}, {entry.licence.split(' (')[0]}, into {folder})")
        a, b, c = (folder / PurePosixPath(f.path).name for f in entry.files)
        return spec, (a, b, c), entry.tag_height
    folder = Path(spec)
    if not folder.is_dir():
        raise ConfigError(f"radio site {spec}: no such folder (a site of your own is a folder holding "
                          f"{', '.join(FOLDER_FILES)})")
    a, b, c = (folder / n for n in FOLDER_FILES)
    return folder.name or spec, (a, b, c), None


def load_site(spec: str, tag_height: float | None = None) -> Site:
    """The site ``spec`` (a registry name or a folder) read and checked; ``tag_height`` (metres) for readings
    without a ``z`` column, else the registry's (0 for a folder)."""
    name, (fa, fl, fr), registry_height = site_files(spec)
    ids, anchors = parse_anchors(read_text(fa), str(fa))
    layout = parse_layout(read_text(fl), str(fl))
    check_anchors(anchors, ids, layout, str(fa))
    height = tag_height if tag_height is not None else (registry_height or 0.0)
    xy, z, rss = parse_readings(read_text(fr), str(fr), ids, height)
    return Site(name, ids, anchors, layout, xy, z, rss)


def read_text(path: Path) -> str:
    """A site file's text: a regular file (a FIFO or a device is refused, never waited on) of at most
    :data:`MAX_BYTES`; a one-line ConfigError otherwise."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise ConfigError(f"cannot read {path}: {exc.strerror or exc}") from None
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise ConfigError(f"cannot read {path}: not a regular file")
        if st.st_size > MAX_BYTES:
            raise ConfigError(f"{path} is larger than {MAX_BYTES >> 20} MB")
        os.set_blocking(fd, True)
        data = f.read(MAX_BYTES + 1)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ConfigError(f"{path} is not UTF-8 text") from None


def table(text: str, where: str, need: tuple[str, ...]) -> tuple[list[str], list[list[str]]]:
    """A CSV's header and rows; a one-line ConfigError when a column of ``need`` is missing or a row is short."""
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        raise ConfigError(f"{where} is empty (it needs the columns {', '.join(need)})")
    header = [h.strip() for h in rows[0]]
    missing = [n for n in need if n not in header]
    if missing:
        raise ConfigError(f"{where} has no column {', '.join(missing)} (its columns: {', '.join(header)})")
    body = [r for r in rows[1:] if any(v.strip() for v in r)]
    if len(body) > MAX_ROWS:
        raise ConfigError(f"{where} has {len(body)} rows, more than the {MAX_ROWS} a site may have")
    for i, r in enumerate(body):
        if len(r) != len(header):
            raise ConfigError(f"{where} row {i + 2} has {len(r)} values, not the header's {len(header)}")
    if not body:
        raise ConfigError(f"{where} has no rows")
    return header, body


def numbers(body: list[list[str]], col: int, where: str, name: str, *, missing: bool = False) -> np.ndarray:
    """Column ``col`` as floats: finite numbers (NaN for an empty value when ``missing`` allows it); a one-line
    ConfigError naming the row otherwise."""
    out = np.empty(len(body))
    for i, r in enumerate(body):
        text = r[col].strip()
        try:
            v = float(text) if text or not missing else math.nan
        except ValueError:
            v = None
        if v is None or (not math.isfinite(v) and not (missing and not text)):
            raise ConfigError(f"{where} row {i + 2}: {name} must be a finite number (got {text!r})")
        out[i] = v
    return out


def parse_anchors(text: str, where: str) -> tuple[tuple[int, ...], np.ndarray]:
    """The anchors' ids and positions (N x 3) from ``id,x,y,z``; ids whole and distinct."""
    header, body = table(text, where, ("id", "x", "y", "z"))
    ids = numbers(body, header.index("id"), where, "id")
    if not all(float(i).is_integer() and 0 <= i < 10**9 for i in ids) or len(set(ids)) != len(ids):
        raise ConfigError(f"{where}: anchor ids must be distinct whole numbers (got {', '.join(map(str, ids))})")
    xyz = np.stack([numbers(body, header.index(k), where, k) for k in ("x", "y", "z")], axis=1)
    return tuple(int(i) for i in ids), xyz


def parse_layout(text: str, where: str) -> np.ndarray:
    """The wall polyline (M x 2) from ``x,y``, closed (its first vertex repeated at the end if it is not)."""
    header, body = table(text, where, ("x", "y"))
    xy = np.stack([numbers(body, header.index(k), where, k) for k in ("x", "y")], axis=1)
    if len(xy) < 3:
        raise ConfigError(f"{where}: the walls need at least 3 vertices (got {len(xy)})")
    return xy if np.array_equal(xy[0], xy[-1]) else np.vstack([xy, xy[:1]])


def check_anchors(anchors: np.ndarray, ids: tuple[int, ...], layout: np.ndarray, where: str) -> None:
    """A one-line ConfigError for an anchor outside the walls' bounding box."""
    lo, hi = layout.min(axis=0), layout.max(axis=0)
    for i, (x, y, _) in zip(ids, anchors, strict=True):
        if not (lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1]):
            raise ConfigError(f"{where}: anchor {i} at ({x:g}, {y:g}) is outside the walls' box "
                              f"[{lo[0]:g}, {hi[0]:g}] x [{lo[1]:g}, {hi[1]:g}] m")


def parse_readings(text: str, where: str, ids: tuple[int, ...],
                   tag_height: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The transmitter's positions (K x 2), heights (K) and the RSS (K x N, NaN where nothing was heard) from
    ``x,y[,z],rssi_<id>...``."""
    need = ("x", "y", *(f"rssi_{i}" for i in ids))
    header, body = table(text, where, need)
    xy = np.stack([numbers(body, header.index(k), where, k) for k in ("x", "y")], axis=1)
    z = numbers(body, header.index("z"), where, "z") if "z" in header else np.full(len(body), float(tag_height))
    rss = np.stack([numbers(body, header.index(f"rssi_{i}"), where, f"rssi_{i}", missing=True) for i in ids],
                   axis=1)
    return xy, z, rss
