"""The measured radio sites kept beside the repository (:data:`SHARED_RADIO`, one folder per site, each file under
its upstream file name) re-laid as a ``fleet radio fetch --mirror`` folder of symlinks (``MIRROR/<site
name>/<upstream file name>``). The tests reach those measurements only through such a mirror, and skip when they
are absent."""

from __future__ import annotations

from pathlib import Path

import pytest

from fleet_emu.world.sites import sites
from tests.harness.map_mirror import link_mirror

SHARED_RADIO = Path(__file__).resolve().parents[2].parent / "shared" / "radio"


def build_mirror(root: Path) -> Path:
    """``root`` made a mirror of every registry site, symlinks into SHARED_RADIO; a skip when they are absent."""
    return link_mirror(root, SHARED_RADIO, sites().values(), lambda entry, f: SHARED_RADIO / entry.name / f.name,
                       "measured radio sites")


def fetched(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    """Every registry site fetched through a mirror into this test's own user cache; the first site's name."""
    from fleet_emu.world.fetch import fetch

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    mirror = build_mirror(tmp_path / "mirror")
    for entry in sites().values():
        fetch(entry, str(mirror))
    return next(iter(sites()))
