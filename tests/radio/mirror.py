"""The measured radio sites kept beside the repository (:data:`SHARED_RADIO`, one folder per site, each file under
its upstream file name) re-laid as a ``fleet radio fetch --mirror`` folder of symlinks (``MIRROR/<site
name>/<upstream file name>``). The tests reach those measurements only through such a mirror, and skip when they
are absent."""

from __future__ import annotations

from pathlib import Path

import pytest

from fleet_emu.world.sites import sites

SHARED_RADIO = Path(__file__).resolve().parents[2].parent / "shared" / "radio"


def build_mirror(root: Path) -> Path:
    """``root`` made a mirror of every registry site, symlinks into SHARED_RADIO; a skip when they are absent."""
    if not SHARED_RADIO.is_dir():
        pytest.skip(f"the measured radio sites are not beside the repository ({SHARED_RADIO} is absent); the "
                    "tests that fetch them through --mirror need them")
    for entry in sites().values():
        (root / entry.name).mkdir(parents=True, exist_ok=True)
        for f in entry.files:
            name = Path(f.path).name
            source = SHARED_RADIO / entry.name / name
            if not source.is_file():
                pytest.skip(f"{source} is absent from the measured sites beside the repository")
            (root / entry.name / name).symlink_to(source)
    return root


def fetched(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    """Every registry site fetched through a mirror into this test's own user cache; the first site's name."""
    from fleet_emu.world.fetch import fetch

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    mirror = build_mirror(tmp_path / "mirror")
    for entry in sites().values():
        fetch(entry, str(mirror))
    return next(iter(sites()))
