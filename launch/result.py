"""What one run gives back: :class:`Result`, the ``result.json`` contract
(docs/reference/result.md) with the coverage curve beside it, readable like the dict it was."""

from __future__ import annotations

import dataclasses
import functools
import json
from collections.abc import Iterator, Mapping
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

#: ``result.json`` keys that depend on the clock, the processes, the engine or the bus, not on the seed: every
#: other key is the same for a seed whatever the engine (docs/design/determinism.md).
UNTIMED = frozenset({"run_id", "decision_ms", "agent_peak_rss_kb", "ticks_per_second", "pids", "recording",
                     "wall_seconds", "engine", "authenticated", "signal", "bus"})


def deterministic(data: Mapping[str, Any]) -> dict[str, Any]:
    """``result.json`` without the :data:`UNTIMED` keys, nor the scenario's ``hosts`` (where the robots ran):
    what a seed reproduces on every engine, on one machine or several."""
    out = {k: v for k, v in data.items() if k not in UNTIMED}
    if isinstance(out.get("scenario"), dict) and "hosts" in out["scenario"]:
        out["scenario"] = {k: v for k, v in out["scenario"].items() if k != "hosts"}
    return out


def unexpected_failures(data: Mapping[str, Any]) -> list[str]:
    """The robots of ``result.json``'s ``failed`` that no fault of the scenario crashed (``faults``): the failures
    nobody asked for, which make a run's exit code 1 and a study's row failed."""
    crashed = {f.get("robot") for f in data.get("faults", []) if isinstance(f, dict)}
    return [r for r in data.get("failed", []) if r not in crashed]


@dataclasses.dataclass(frozen=True)
class Result(Mapping[str, Any]):
    """A run's result: ``result["ticks"]`` (or ``result.ticks`` for the main keys) reads ``result.json``'s keys;
    :meth:`coverage_curve` gives coverage against ticks; ``out_dir`` is where the run's files are (None when
    nothing was kept)."""

    data: dict[str, Any]
    curve: tuple[tuple[int, float], ...] = ()
    out_dir: Path | None = None

    def __getitem__(self, key: str) -> Any:
        return self.data[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.data)

    def __len__(self) -> int:
        return len(self.data)

    @property
    def ticks(self) -> int:
        return int(self.data["ticks"])

    @property
    def completed(self) -> bool:
        return bool(self.data["completed"])

    @property
    def coverage(self) -> float:
        return float(self.data["coverage"])

    def coverage_curve(self) -> tuple[np.ndarray, np.ndarray]:
        """Ticks and the team's coverage at each (from the world's state messages)."""
        if not self.curve:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        ticks, cov = zip(*self.curve, strict=True)
        return np.asarray(ticks, dtype=np.int64), np.asarray(cov, dtype=float)

    def to_dict(self) -> dict[str, Any]:
        return dict(self.data)


def result_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of ``result.json``, shipped in the package as
    ``fleet_emu/launch/schemas/result.schema.json`` (docs/reference/result.md documents each key)."""
    text = (resources.files("fleet_emu.launch") / "schemas" / "result.schema.json").read_text()
    schema: dict[str, Any] = json.loads(text)
    return schema


@functools.cache
def _validator() -> Any:
    try:
        import jsonschema
    except ImportError:
        raise ImportError("validate_result needs the jsonschema package (pip install 'fleet-emu[dev]')") from None
    schema = result_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def validate_result(data: Mapping[str, Any]) -> None:
    """Check a run's ``result.json`` (or :attr:`Result.data`) against :func:`result_schema`, as it would be
    written (through JSON); ValueError listing every key that breaks it. Needs ``jsonschema`` (the test extra)."""
    doc = json.loads(json.dumps(dict(data)))
    errors = sorted(_validator().iter_errors(doc), key=lambda e: list(map(str, e.absolute_path)))
    if errors:
        lines = [f"{'/'.join(map(str, e.absolute_path)) or '(top)'}: {e.message}" for e in errors]
        raise ValueError(f"result.json breaks its schema ({len(errors)} error(s)):\n  " + "\n  ".join(lines))


def write_json_atomic(path: Path, obj: Any) -> None:
    """Write JSON to ``path`` through a temporary file and a rename, so that a reader (or a crash) never sees
    half a file; the temporary file is removed when the write fails (a full disk)."""
    from fleet_emu.launch.outdir import write_json

    write_json(path, obj)
