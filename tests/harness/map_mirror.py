"""Map mirrors for the tests: the public maps kept beside the repository (:data:`SHARED_MAPS`, laid out by
origin: ``stage/hospital_section.png``, ``ros/turtlebot3_world/map.pgm``) re-laid as a ``fleet maps fetch
--mirror`` folder of symlinks (``MIRROR/<map name>/<upstream file name>``), and an HTTP server on 127.0.0.1 that
serves a folder. The tests reach those maps only through such a mirror, and skip when they are absent."""

from __future__ import annotations

import contextlib
import functools
import http.server
import threading
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import TypeVar

import pytest

from fleet_emu.world.registry import MapFile, Pinned, registry

E = TypeVar("E", bound=Pinned)

SHARED_MAPS = Path(__file__).resolve().parents[2].parent / "shared" / "maps"
#: Where each upstream repository's files are kept under SHARED_MAPS.
FOLDERS = {"rtv/Stage": "stage", "ROBOTIS-GIT/turtlebot3": "ros/turtlebot3_world",
           "ros-navigation/navigation2": "ros/nav2_bringup"}


def link_mirror(root: Path, shared: Path, entries: Iterable[E], source: Callable[[E, MapFile], Path],
                what: str) -> Path:
    """``root`` made a mirror of ``entries`` (``<root>/<name>/<file name>``), each file a symlink to
    ``source(entry, file)`` under ``shared``, the data kept beside the repository; a skip when it is absent."""
    if not shared.is_dir():
        pytest.skip(f"the {what} are not beside the repository ({shared} is absent); the tests that fetch them "
                    "through --mirror need them")
    for entry in entries:
        (root / entry.name).mkdir(parents=True, exist_ok=True)
        for f in entry.files:
            target = source(entry, f)
            if not target.is_file():
                pytest.skip(f"{target} is absent from the {what} beside the repository")
            (root / entry.name / f.name).symlink_to(target)
    return root


def build_mirror(root: Path) -> Path:
    """``root`` made a mirror of every registry map, symlinks into SHARED_MAPS; a skip when they are absent."""
    return link_mirror(root, SHARED_MAPS, registry().values(),
                       lambda entry, f: SHARED_MAPS / FOLDERS[entry.repo] / f.name, "public maps")


def files_in(folder: Path) -> list[Path]:
    """Every file under ``folder`` (none when it does not exist)."""
    return [p for p in folder.rglob("*") if p.is_file()] if folder.exists() else []


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:  # the base class names it format
        pass


@contextlib.contextmanager
def serve(folder: Path) -> Iterator[str]:
    """An HTTP server on 127.0.0.1 serving ``folder`` for the ``with`` block; its base URL."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(_Quiet, directory=str(folder)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()
        thread.join()
