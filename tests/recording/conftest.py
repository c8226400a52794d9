"""The recording tests' fixtures: the official Foxglove clients (node), installed once per lock file."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from pathlib import Path

import pytest

JS = Path(__file__).resolve().parents[1] / "js"


@pytest.fixture(scope="session")
def js_clients() -> Path:
    """A folder with the pinned clients installed and this repository's scripts beside them."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if node is None or npm is None:
        pytest.skip("node and npm are needed for the official Foxglove clients")
    lock = (JS / "package-lock.json").read_bytes()
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    folder = base / "fleet-emu" / "js-clients" / hashlib.sha256(lock).hexdigest()[:16]
    if not (folder / "node_modules" / ".package-lock.json").is_file():
        folder.mkdir(parents=True, exist_ok=True)
        for name in ("package.json", "package-lock.json"):
            shutil.copy(JS / name, folder / name)
        try:
            proc = subprocess.run([npm, "ci", "--no-audit", "--no-fund"], cwd=folder, capture_output=True,
                                  text=True, timeout=600)
        except subprocess.TimeoutExpired:
            pytest.skip("npm ci timed out (no npm registry?)")
        if proc.returncode != 0:
            lines = proc.stderr.strip().splitlines()
            pytest.skip(f"npm ci failed (no npm registry?): {lines[-1] if lines else proc.returncode}")
    for script in JS.glob("*.mjs"):
        shutil.copy(script, folder / script.name)
    return folder
