"""``fleet maps``: the maps a run can name (built-in and registry, each registry map "fetched" or the command that
fetches it), and ``fleet maps fetch NAME... | --all [--mirror URL|DIR]``, which downloads registry maps into the
user cache directory, checks every file's sha256 and prints each map's source and licence.

A checksum mismatch, an unknown name or an unreachable source is one line on stderr and exit 2, and leaves
nothing in the cache (``world/fetch.py``); so do Ctrl-C (exit 130) and SIGTERM (exit 143) during a fetch.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any, TextIO

from fleet_emu.core.errors import ConfigError
from fleet_emu.launch.signals import sigterm_unwinds

MIRROR_HELP = ("read the files from a mirror laid out as MIRROR/<map name>/<upstream file name>: a folder, or a base "
               "URL (http:// or https://); a machine's cache folder (`fleet maps` prints it) is such a mirror")


def add_parser(sub: Any) -> None:
    """The ``maps`` subcommand of ``fleet`` and its ``fetch``."""
    m = sub.add_parser("maps", help="list the maps (built-in and registry); `fleet maps fetch NAME` downloads one",
                       usage="fleet maps [-h] [fetch (NAME... | --all) [--mirror URL|DIR] [--force]]",
                       description="With no command: list the maps a run names with --map, the built-in ones "
                                   "(generated from the seed) and the registry's public maps (fetched once into the "
                                   "user cache), each with 'fetched' or the command that fetches it.")
    msub = m.add_subparsers(dest="maps_command", metavar="fetch")
    f = msub.add_parser("fetch", help="download registry maps into the user cache, checked against their sha256",
                        description="Download registry maps into the user cache directory (honours "
                                    "XDG_CACHE_HOME), check every file against its sha256, and print each map's "
                                    "source and licence. Nothing is kept of a map that fails.")
    f.add_argument("names", nargs="*", metavar="NAME", help="registry map names (see `fleet maps`)")
    f.add_argument("--all", action="store_true", help="every registry map")
    f.add_argument("--mirror", metavar="URL|DIR", help=MIRROR_HELP)
    f.add_argument("--force", action="store_true", help="download again even when the cached copy is intact")


def cmd_maps(args: argparse.Namespace, out: TextIO | None = None) -> int:
    """``fleet maps`` (a listing) or ``fleet maps fetch``; the exit code. Errors are FleetErrors (exit 2)."""
    out = out or sys.stdout
    if getattr(args, "maps_command", None) == "fetch":
        return fetch_maps(args.names, every=args.all, mirror=args.mirror, force=args.force, out=out)
    list_maps(out)
    return 0


def list_maps(out: TextIO) -> None:
    """Every map a run can name: the built-in ones, then the registry's with their size, source and state."""
    from fleet_emu.world.maps import BUILTIN_MAPS
    from fleet_emu.world.registry import cache_dir, fetch_command, is_fetched, registry

    print("built-in (generated from the seed; --cell-size scales them):", file=out)
    for name, desc in BUILTIN_MAPS.items():
        print(f"  {name:18s} {desc}", file=out)
    print(f"registry (public maps, fetched once into {cache_dir()}):", file=out)
    for name, entry in registry().items():
        w, h = entry.size_m
        state = "fetched" if is_fetched(name) else f"`{fetch_command(name)}`"
        licence = entry.licence.split(" (")[0]
        print(f"  {name:18s} {w:.4g} x {h:.4g} m, {entry.repo}, {licence}: {state}", file=out)
        print(f"  {'':18s} {entry.description}", file=out)


def fetch_maps(names: list[str], *, every: bool = False, mirror: str | None = None, force: bool = False,
               out: TextIO | None = None) -> int:
    """Fetch the maps ``names`` (or every registry map), each line saying where it came from and its licence;
    a FleetError at the first failure, the maps fetched before it kept."""
    from fleet_emu.world.fetch import entries_in, fetch
    from fleet_emu.world.registry import registry

    out = out or sys.stdout
    if every == bool(names):
        raise ConfigError("fleet maps fetch needs map names or --all (not both); `fleet maps` lists them")
    for entry in entries_in(list(registry()) if every else names):
        with sigterm_unwinds():
            done = fetch(entry, mirror, force=force)
        files = ", ".join(f.path for f in entry.files)
        via = "" if done.cached or mirror is None else f" via {mirror}"
        where = f"already in {done.folder}" if done.cached else f"-> {done.folder}"
        print(f"{entry.name}: {entry.source} {files}{via} {where} (sha256 checked); licence {entry.licence}",
              file=out)
    return 0
