"""The sweep report of a bandwidth study, on hand-made rows: grouped by the radio's rate (absent from an
unlimited run's scenario), kilobytes sent per robot-tick, and the time against bandwidth figure."""

from __future__ import annotations

from pathlib import Path

import pytest

from fleet_emu.sweep.execute import write_tables
from fleet_emu.sweep.report import report
from tests.harness.sweep import row


def _rated(alloc: str, ticks: int, bandwidth: float | None, i: int) -> dict:
    r = row(alloc, 2, ticks) | {"id": str(i), "radio.bytes_sent": 2 * ticks * 1500, "curve": "[0.5, 0.99]",
                                "curve_every": 5}
    return r | ({"scenario.radio.bandwidth": bandwidth} if bandwidth is not None else {})


def test_a_bandwidth_study_is_grouped_by_rate_with_its_bytes(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    rows = [_rated(a, t, b, i) for i, (a, t, b) in enumerate(
        [("nearest", 100, None), ("nearest", 110, None), ("nearest", 300, 16.0), ("nearest", 320, 16.0),
         ("minpos", 90, None), ("minpos", 95, None), ("minpos", 200, 16.0), ("minpos", 210, 16.0)])]
    write_tables(rows, tmp_path)
    report(tmp_path, baseline="nearest", plots=True)
    text = capsys.readouterr().out
    assert "full, loss 0, 16 kbit/s" in text and "sent kB" in text
    assert "310.0 ± 14.1" in text and "105.0 ± 7.1" in text  # nearest limited, unlimited: two groups
    assert "1.50 ± 0.00" in text  # 1500 bytes per robot-tick
    assert (tmp_path / "time_vs_bandwidth.png").stat().st_size > 1000
