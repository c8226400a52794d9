"""Map mirrors for the tests: the public maps kept beside the repository (:data:`SHARED_MAPS`, laid out by
origin: ``stage/hospital_section.png``, ``ros/turtlebot3_world/map.pgm``) re-laid as a ``fleet maps fetch
--mirror`` folder of symlinks (``MIRROR/<map name>/<upstream file name>``), and an HTTP server on 127.0.0.1 that
serves a folder. The tests reach those maps only through such a mirror, and skip when they are absent."""

from __future__ import annotations

import contextlib
import functools
import http.server
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from fleet_emu.world.registry import registry

SHARED_MAPS = Path(__file__).resolve().parents[2].parent / "shared" / "maps"
#: Where each upstream repository's files are kept under SHARED_MAPS.
FOLDERS = {"rtv/Stage": "stage", "ROBOTIS-GIT/turtlebot3": "ros/turtlebot3_world",
           "ros-navigation/navigation2": "ros/nav2_bringup"}


def build_mirror(root: Path) -> Path:
    """``root`` made a mirror of every registry map, symlinks into SHARED_MAPS; a skip when they are absent."""
    if not SHARED_MAPS.is_dir():
        pytest.skip(f"the public maps are not beside the repository ({SHARED_MAPS} is absent); the tests that "
                    "fetch them through --mirror need them")
    for entry in registry().values():
        (root / entry.name).mkdir(parents=True, exist_ok=True)
        for f in entry.files:
            source = SHARED_MAPS / FOLDERS[entry.repo] / f.name
            if not source.is_file():
                pytest.skip(f"{source} is absent from the public maps beside the repository")
            (root / entry.name / f.name).symlink_to(source)
    return root


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
