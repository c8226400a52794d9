"""The names ``result.json``'s module had here before it moved to :mod:`fleet_emu.recording.result` (the one
builder of ``result.json``, its schema beside it), kept for one release: new code imports them from there."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from fleet_emu.recording.result import (
    UNTIMED,
    Result,
    deterministic,
    result_schema,
    unexpected_failures,
    validate_result,
)

__all__ = ["UNTIMED", "Result", "deterministic", "result_schema", "unexpected_failures", "validate_result",
           "write_json_atomic"]


def write_json_atomic(path: Path, obj: Any) -> None:
    """Write JSON to ``path`` through a temporary file and a rename, so that a reader (or a crash) never sees
    half a file; the temporary file is removed when the write fails (a full disk)."""
    from fleet_emu.launch.outdir import write_json

    write_json(path, obj)
