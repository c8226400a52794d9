"""The registry of public maps known by name (``registry.toml`` beside this module), and where a fetched one lives.

Each map is pinned to an upstream commit, with every file's sha256, its licence and its scale. ``fleet maps
fetch NAME`` (:mod:`fleet_emu.world.fetch`) puts its files in the user cache directory, laid out as
``<cache>/<name>/<upstream file name>`` (the same layout a ``--mirror`` has); :func:`local_map` finds them
there, checked against their sha256, for the map loader (:func:`fleet_emu.world.maps.load_map`).

The cache is ``platformdirs.user_cache_dir("fleet-emu")/maps``: ``$XDG_CACHE_HOME/fleet-emu/maps`` (by default
``~/.cache/fleet-emu/maps``) on Linux, ``~/Library/Caches/fleet-emu/maps`` on macOS, ``%LOCALAPPDATA%`` on
Windows.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import tomllib
from pathlib import Path, PurePosixPath
from typing import Any, ClassVar, Protocol

from fleet_emu.core.errors import MapError
from fleet_emu.core.setting_names import near

REGISTRY_FILE = Path(__file__).resolve().parent / "registry.toml"
RAW_URL = "https://raw.githubusercontent.com/{repo}/{commit}/{path}"


@dataclasses.dataclass(frozen=True)
class MapFile:
    """One upstream file of a map: its path in the repository and its sha256."""

    path: str
    sha256: str

    @property
    def name(self) -> str:
        """The file's name, as it is kept in the cache and looked for in a mirror."""
        return PurePosixPath(self.path).name


class Upstream:
    """The addresses of an entry kept at ``repo`` pinned to ``commit`` (a map here, a radio site in
    ``world/sites.py``); the dataclasses that inherit it declare the two fields."""

    repo: str
    commit: str

    def url(self, f: MapFile) -> str:
        """The file's upstream address, pinned to the commit."""
        return RAW_URL.format(repo=self.repo, commit=self.commit, path=f.path)

    @property
    def source(self) -> str:
        """``owner/repo@commit`` (the commit abbreviated), for listings."""
        return f"{self.repo}@{self.commit[:10]}"


@dataclasses.dataclass(frozen=True)
class RegistryMap(Upstream):
    """A public map: where it comes from (``repo`` at ``commit``), its licence, its files, and how it becomes a
    grid: a bitmap at ``resolution`` m/px (square pixels), or, with ``yaml``, the ROS map_server YAML among its
    files. ``pixels`` is (width, height); ``world_size`` Stage's floorplan size in metres, when a world file
    gives one; ``scale`` says where the scale comes from."""

    name: str
    description: str
    repo: str
    commit: str
    licence: str
    files: tuple[MapFile, ...]
    pixels: tuple[int, int]
    resolution: float
    scale: str
    yaml: str | None = None
    world_size: tuple[float, float] | None = None
    #: What it is, as errors name it, and its folder under the user cache (:func:`cache_dir`).
    kind: ClassVar[str] = "map"
    cache: ClassVar[str] = "maps"

    @property
    def size_m(self) -> tuple[float, float]:
        """Width and height in metres, as fleet-emu reads the map (square pixels of ``resolution``)."""
        return self.pixels[0] * self.resolution, self.pixels[1] * self.resolution

    @property
    def entry_file(self) -> str:
        """The file the loader opens: the YAML, or the bitmap."""
        return self.yaml if self.yaml is not None else self.files[0].name


class Pinned(Protocol):
    """What fetching needs of a registry entry, a map or a radio site (``world/sites.py``): its name, its files
    and their pinned addresses, its licence, what it is (``kind``, for messages) and its cache folder's name."""

    kind: ClassVar[str]
    cache: ClassVar[str]

    @property
    def name(self) -> str: ...

    @property
    def files(self) -> tuple[MapFile, ...]: ...

    @property
    def licence(self) -> str: ...

    @property
    def source(self) -> str: ...

    def url(self, f: MapFile) -> str: ...


def _entry(name: str, raw: dict[str, Any], sources: dict[str, Any]) -> RegistryMap:
    src = sources[raw["source"]]
    files = tuple(MapFile(f["path"], f["sha256"]) for f in raw["files"])
    size = raw.get("world_size")
    return RegistryMap(name=name, description=raw["description"], repo=src["repo"], commit=src["commit"],
                       licence=src["licence"], files=files, pixels=(int(raw["pixels"][0]), int(raw["pixels"][1])),
                       resolution=float(raw["resolution"]), scale=raw["scale"], yaml=raw.get("yaml"),
                       world_size=(float(size[0]), float(size[1])) if size else None)


@functools.cache
def registry() -> dict[str, RegistryMap]:
    """Every registry map by name, in the file's order."""
    raw = tomllib.loads(REGISTRY_FILE.read_text())
    return {name: _entry(name, m, raw["sources"]) for name, m in raw["maps"].items()}


def lookup(name: str) -> RegistryMap:
    """The registry map ``name``; a one-line MapError naming the known ones otherwise."""
    try:
        return registry()[name]
    except KeyError:
        raise MapError(f"unknown map {name!r}{near(name, registry())} (the registry has: {', '.join(registry())}; "
                       "`fleet maps` lists them)") from None


def cache_dir(kind: str = "maps") -> Path:
    """Where fetched maps are kept (the module docstring says where that is on each system); ``kind``
    ``"radio"``: where fetched radio sites are, beside them."""
    import platformdirs

    return Path(platformdirs.user_cache_dir("fleet-emu", appauthor=False)) / kind


def fetch_command(name: str) -> str:
    return f"fleet maps fetch {name}"


def sha256_of(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def verified(entry: Pinned, folder: Path) -> bool:
    """Whether ``folder`` holds every file of ``entry`` with its sha256."""
    try:
        return all(sha256_of(folder / f.name) == f.sha256 for f in entry.files)
    except OSError:
        return False


def is_fetched(name: str) -> bool:
    """Whether the map is in the cache, every file intact."""
    return verified(lookup(name), cache_dir() / name)


def local_map(name: str) -> Path:
    """The cached file the loader reads for ``name`` (its YAML or its bitmap), every file checked against its
    sha256; a one-line MapError naming the command that fetches it when it is not there (or was altered)."""
    entry = lookup(name)
    folder = cache_dir() / name
    if not verified(entry, folder):
        state = "is not fetched" if not folder.exists() else "is incomplete or altered in the cache"
        raise MapError(f"map {name} {state}: run `{fetch_command(name)}` (it downloads {entry.source}, "
                       f"{entry.licence.split(' (')[0]}, into {folder})")
    return folder / entry.entry_file
