"""``fleet recover RUN_DIR``: a run whose launcher died (SIGKILL, a power cut, a full disk) made whole.

Under the folder's lock (:mod:`.outdir`: refused while a run is writing there), a cut ``run.mcap`` is renamed
``run.mcap.cut`` and rewritten from it as an indexed MCAP file every reader opens
(:func:`fleet_emu.recording.recover.rewrite`); a missing ``result.json`` is written from what the recording
holds, with ``reason`` ``crashed``. Each step is atomic and the whole is idempotent: a recovery cut short is
finished by the next one. ``fleet report`` recovers each run folder it reads the same way first.
"""

from __future__ import annotations

import argparse
import contextlib
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from fleet_emu.core.errors import ReportError
from fleet_emu.launch.outdir import FolderLock, lock_folder, write_json

RECORDING, CUT, RESULT = "run.mcap", "run.mcap.cut", "result.json"


def add_parser(sub: Any) -> None:
    rec = sub.add_parser("recover", help="make a cut run.mcap whole (kept as run.mcap.cut) and write a missing "
                                         "result.json from it (reason crashed)")
    rec.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="the run's folder (or its run.mcap)")


def cmd_recover(args: argparse.Namespace) -> int:
    for line in recover(args.run_dir):
        print(line)
    return 0


def run_folder(path: Path) -> Path:
    """RUN_DIR, or the folder of RUN_DIR/run.mcap (or of its ``.cut``)."""
    if path.is_file() and path.name in (RECORDING, CUT):
        return path.parent
    if not path.is_dir():
        raise ReportError(f"no such run folder: {path}")
    return path


def recover(path: Path) -> list[str]:
    """Recover the run in ``path`` (see the module); the lines that say what was done. ReportError (one line)
    when there is no recording, ConfigError when another process holds the folder."""
    folder = run_folder(path)
    lock = lock_folder(folder, flag="fleet recover:")
    try:
        return _recover(folder)
    finally:
        lock.release()


def is_cut(folder: Path) -> bool:
    """Whether the run in ``folder`` has a cut (or half-recovered) recording."""
    from fleet_emu.recording.recover import is_whole

    mcap = folder / RECORDING
    return (folder / CUT).exists() if not mcap.exists() else not is_whole(mcap)


@contextlib.contextmanager
def reporting(paths: list[Path], partial: bool = False) -> Iterator[list[str]]:
    """For ``fleet report``: each run folder among ``paths`` (a folder, or its ``run.mcap``) locked while the
    report writes there (refused while a run does), and recovered first when its recording is cut; yields what
    the recoveries did. A cut recording beside a ``result.json`` is not a crashed run's (its launcher wrote the
    result, so it closed the recording): it was cut since, and is refused, saying how much of it reads, unless
    ``partial``."""
    folders = sorted({run_folder(p) for p in paths if p.is_dir() or (p.name == RECORDING and p.is_file())}, key=str)
    locks: list[FolderLock] = []
    said: list[str] = []
    try:
        for folder in folders:
            locks.append(lock_folder(folder, flag="fleet report:"))
            if is_cut(folder):
                if not partial and (folder / RESULT).exists():
                    raise ReportError(_cut_line(folder))
                said += _recover(folder)
        yield said
    finally:
        for lock in locks:
            lock.release()


def _cut_line(folder: Path) -> str:
    """The refusal of a finished run's cut recording: how much of it reads."""
    from fleet_emu.recording.read import recorded_count
    from fleet_emu.recording.recover import readable

    mcap = folder / RECORDING if (folder / RECORDING).exists() else folder / CUT
    messages, read, size = readable(mcap)
    of = f" of the {recorded} its run recorded" if (recorded := recorded_count(folder / RECORDING)) else ""
    return (f"{mcap} is cut: {messages} messages read{of}, {read} of its {size} bytes; pass --partial to report "
            "that much")


def _recover(folder: Path) -> list[str]:
    from fleet_emu.recording.read import load_recording
    from fleet_emu.recording.recover import crashed_result, is_whole, rewrite, wall_span

    mcap, cut, said = folder / RECORDING, folder / CUT, []
    if mcap.exists() and not is_whole(mcap):
        os.replace(mcap, cut)  # first: a recovery cut short after it is finished by the next one
    elif not mcap.exists() and not cut.exists():
        raise ReportError(f"{folder} holds no {RECORDING}")
    if not mcap.exists():
        done = rewrite(cut, mcap)
        said.append(f"{mcap}: rewritten whole from its cut original ({done.messages} messages; the original is "
                    f"kept as {cut})")
    if not (folder / RESULT).exists():
        run = load_recording(mcap)
        data = crashed_result(run, wall_span(mcap))
        write_json(folder / RESULT, data)
        said.append(f"{folder / RESULT}: written from the recording (reason crashed, tick {data['ticks']}, "
                    f"coverage {data['coverage']:.3f})")
    return said or [f"{folder}: nothing to recover ({RECORDING} is whole and {RESULT} is there)"]
