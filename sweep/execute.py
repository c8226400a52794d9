"""Running a study's points: one row per run, in parallel (a local process pool, or a Dask cluster), written as
they finish to ``rows.jsonl`` (so an interrupted sweep resumes) and at the end to ``results.parquet`` and
``results.csv``.

A row is every ``result.json`` key flattened (``radio.sent``, ``scenario.radio.comm_range``; lists as JSON),
the point's parameters (``param.allocator``, ``param.robots``, ..., ``param.seed``), its ``id``, ``status``
(``ok`` or ``failed``), ``error``, its wall and CPU seconds (``point_seconds``, ``point_cpu_seconds``: the
worker's CPU time, what the run costs on an idle core) and the coverage curve (``curve``: JSON, one value
every ``curve_every`` ticks).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import errno
import json
import multiprocessing
import os
import signal
import threading
import time
import traceback
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

from fleet_emu.recording.result import unexpected_failures
from fleet_emu.sweep import record
from fleet_emu.sweep.record import Keep
from fleet_emu.sweep.study import Point

ROWS = "rows.jsonl"
PARQUET = "results.parquet"
CSV = "results.csv"
CURVE_EVERY = 5
#: Seconds a Dask scheduler has to answer ``--dask``'s handshake.
HANDSHAKE_S = 10.0


def run_point(point: Point, keep: Keep | None = None) -> dict[str, Any]:
    """One run of a study as a row; never raises (a failed run is a row with its error). Top-level and
    picklable: a pool worker or a Dask worker runs it. ``keep`` says which runs keep their folder
    (:mod:`fleet_emu.sweep.record`)."""
    row: dict[str, Any] = {"id": point.id, "engine": point.engine}
    row |= {f"param.{k}": v for k, v in point.params.items()}
    record.clear(point, keep)
    t0, cpu0 = time.perf_counter(), time.process_time()
    try:
        result = record.run(point, keep.folder(point.id) if keep and record.records_now(point, keep) else None)
    except Exception as exc:  # the row says what went wrong; the sweep goes on
        last = traceback.extract_tb(exc.__traceback__)[-1:] if exc.__traceback__ else []
        where = f" ({last[0].filename.rsplit('/', 1)[-1]}:{last[0].lineno})" if last else ""
        return record.settle(point, keep, row | group_of(point) | {
            "status": "failed", "error": f"{type(exc).__name__}: {exc}{where}",
            "point_seconds": round(time.perf_counter() - t0, 3),
            "point_cpu_seconds": round(time.process_time() - cpu0, 3)})
    seconds, cpu = round(time.perf_counter() - t0, 3), round(time.process_time() - cpu0, 3)
    data = dict(flatten(result.to_dict()))
    data.pop("engine", None)
    unasked = unexpected_failures(result.to_dict())  # a robot the scenario crashed ([[faults]]) is no failure
    return record.settle(point, keep, row | data | {
        "status": "failed" if unasked else "ok", "error": f"robots failed: {json.dumps(unasked)}" if unasked else None,
        "point_seconds": seconds, "point_cpu_seconds": cpu, "curve_every": CURVE_EVERY, "curve": curve(result)})


def group_of(point: Point) -> dict[str, Any]:
    """The keys ``fleet sweep report`` groups by (map, radio, map sync, robots), for a row that holds no result."""
    from fleet_emu.core.radio import RadioConfig

    sc, radio = point.scenario, point.scenario.get("radio", {})
    loss = RadioConfig(comm=radio.get("comm", "wall"), loss=radio.get("loss", 0.0)).applied_loss
    return {"map": sc.get("map"), "robots": sc.get("robots"), "comm": radio.get("comm"), "loss_applied": loss,
            "map_sync": sc.get("map_sync", True)}


def curve(result: Any) -> str:
    """The coverage curve of a run as a row's ``curve`` (JSON: one value every :data:`CURVE_EVERY` ticks)."""
    ticks, cov = result.coverage_curve()
    return json.dumps([round(float(c), 4) for t, c in zip(ticks, cov, strict=True) if t % CURVE_EVERY == 0])


def flatten(d: dict[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    """Nested dicts as dotted keys; lists as JSON text (one cell of a CSV)."""
    for k, v in d.items():
        if isinstance(v, dict):
            yield from flatten(v, f"{prefix}{k}.")
        elif isinstance(v, list | tuple):
            yield f"{prefix}{k}", json.dumps(v)
        else:
            yield f"{prefix}{k}", v


def read_rows(out: Path) -> list[dict[str, Any]]:
    """The rows written so far (the last row of an id wins; a line cut by a crash or a full disk is skipped, so
    its point runs again)."""
    path = out / ROWS
    rows: dict[str, dict[str, Any]] = {}
    if path.exists():
        for line in path.read_bytes().split(b"\n"):
            try:
                row = json.loads(line)
            except (json.JSONDecodeError, UnicodeDecodeError):
                continue
            if isinstance(row, dict) and isinstance(row.get("id"), str):
                rows[row["id"]] = row
    return list(rows.values())


class RowWriter:
    """Appends each finished row to ``rows.jsonl`` at once, one line in one write, so an interrupted sweep loses
    nothing. A line left cut by a full disk or a crash is closed first, so that the next row is a line of its
    own (the cut one is skipped when read: its point runs again). An OSError (a full disk) is the caller's."""

    def __init__(self, out: Path) -> None:
        # never through a link planted there (an ELOOP, said by the caller as any OSError)
        self._fd = os.open(out / ROWS, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
        self._torn = os.fstat(self._fd).st_size > 0 and _last_byte(out / ROWS) != b"\n"

    def write(self, row: dict[str, Any]) -> None:
        data = (b"\n" if self._torn else b"") + json.dumps(row, default=str).encode() + b"\n"
        self._torn = True  # until the whole line is written: a failed write may leave part of it
        written = os.write(self._fd, data)
        if written != len(data):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self._torn = False

    def close(self) -> None:
        os.close(self._fd)


def _last_byte(path: Path) -> bytes:
    with path.open("rb") as f:
        f.seek(-1, os.SEEK_END)
        return f.read(1)


def execute(points: list[Point], jobs: int, on_row: Callable[[dict[str, Any]], None], dask: Any = None,
            keep: Keep | None = None) -> None:
    """Run the points (in any order), calling ``on_row`` with each row as it finishes; ``dask`` is a
    :func:`connect_dask` client (or None for a local pool of ``jobs`` processes); ``keep``: the runs whose
    folders stay (:mod:`fleet_emu.sweep.record`)."""
    if dask is not None:
        _on_dask(points, dask, on_row, keep)
    elif jobs <= 1:
        for p in points:
            on_row(run_point(p, keep))
    else:
        ctx = multiprocessing.get_context("spawn")  # never fork: a worker may open Zenoh sessions
        with cf.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
            futures = {pool.submit(run_point, p, keep): p for p in points}
            try:
                for fut in cf.as_completed(futures):
                    on_row(_row_of(fut, futures[fut]))
            except BaseException:
                for fut in futures:
                    fut.cancel()
                _interrupt_workers()
                raise


def _interrupt_workers() -> None:
    """SIGINT to every worker (what a terminal's Ctrl-C does to the whole group): a worker's fleet tears its
    processes down and writes its files before the pool shuts down, also when only this process got SIGTERM.
    The workers are this process's live ``multiprocessing`` children (the pool's are its only ones)."""
    for proc in multiprocessing.active_children():
        with contextlib.suppress(OSError, ValueError):
            if proc.pid is not None:
                os.kill(proc.pid, signal.SIGINT)


def connect_dask(address: str, seconds: float = HANDSHAKE_S) -> Any:
    """A client of the Dask scheduler at ``address``; a ConfigError (one line) when none answers within
    ``seconds``: the scheduler's handshake is tried first under that deadline (:func:`scheduler_answers`), as the
    client's own connect waits without one on a peer that accepts the connection and stays silent."""
    from fleet_emu.core.errors import ConfigError

    try:
        from distributed import Client
    except ImportError:
        raise ConfigError("--dask needs dask[distributed]: pip install 'fleet-emu[sweep]'") from None
    scheduler_answers(address, seconds)
    try:
        return Client(address, timeout=f"{seconds:g}s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise ConfigError(f"--dask {address}: no Dask scheduler answered ({exc})") from None


def scheduler_answers(address: str, seconds: float = HANDSHAKE_S) -> None:
    """Connect to ``address`` and ask the scheduler who it is, the whole exchange within ``seconds``; a
    ConfigError of one line when it refuses, is not a Dask scheduler, or stays silent. Ctrl-C ends the wait."""
    import asyncio

    from distributed.comm import connect

    from fleet_emu.core.errors import ConfigError

    async def identity() -> Any:
        comm = await connect(address, timeout=seconds)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    outcome: dict[str, Any] = {}

    def probe() -> None:
        try:
            outcome["reply"] = asyncio.run(asyncio.wait_for(identity(), seconds))
        except BaseException as exc:  # handed to the waiting thread
            outcome["error"] = exc

    # on its own thread: this one waits in a join, which SIGINT interrupts (asyncio's own SIGINT handling does
    # not reach a connect that is waiting), and SIGTERM's default ends the process
    thread = threading.Thread(target=probe, name="dask-handshake", daemon=True)
    thread.start()
    thread.join(seconds + 2.0)
    try:
        if thread.is_alive():
            raise TimeoutError
        if "error" in outcome:
            raise outcome["error"]
        reply = outcome["reply"]
    except TimeoutError:
        raise ConfigError(f"--dask {address}: no Dask scheduler answered within {seconds:g} s") from None
    except (OSError, ValueError, TypeError) as exc:  # refused, unreachable, a bad address, the comm closed
        raise ConfigError(f"--dask {address}: no Dask scheduler answered ({type(exc).__name__}: "
                          f"{str(exc).splitlines()[0] if str(exc) else 'no reason given'})") from None
    if not (isinstance(reply, dict) and reply.get("type") == "Scheduler"):
        raise ConfigError(f"--dask {address}: the peer there is not a Dask scheduler")


def _on_dask(points: list[Point], client: Any, on_row: Callable[[dict[str, Any]], None], keep: Keep | None) -> None:
    """Each point a task on a Dask distributed cluster: every worker runs whole fleets (and writes the runs it
    keeps under the results folder's path on its own machine)."""
    from distributed import as_completed

    futures = client.map(run_point, points, [keep] * len(points), pure=False, key=[f"fleet-{p.id}" for p in points])
    by_key = {f.key: p for f, p in zip(futures, points, strict=True)}
    for fut in as_completed(futures):
        on_row(_row_of(fut, by_key[fut.key]))


def _row_of(fut: Any, point: Point) -> dict[str, Any]:
    """A future's row; a worker that died is a failed row."""
    try:
        return fut.result()
    except Exception as exc:
        return {"id": point.id, "engine": point.engine, **{f"param.{k}": v for k, v in point.params.items()},
                **group_of(point), "status": "failed", "error": f"worker failed: {type(exc).__name__}: {exc}"}


def write_tables(rows: Iterable[dict[str, Any]], out: Path) -> tuple[list[Path], dict[str, str]]:
    """``results.parquet`` (pyarrow) and ``results.csv`` beside it, one row per run, rows sorted by id, each
    written whole or not at all (a full disk leaves the one before): the tables written, and the error of each
    table that could not be."""
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    from fleet_emu.core.files import write_atomic

    rows = sorted(rows, key=lambda r: r["id"])
    names: dict[str, None] = {}
    for r in rows:
        names |= dict.fromkeys(r)
    table = pa.table({n: _column([r.get(n) for r in rows]) for n in names})
    written, failed = [], {}
    for name, write in ((PARQUET, pq.write_table), (CSV, pacsv.write_csv)):
        try:
            write_atomic(out / name, lambda tmp, w=write: w(table, str(tmp)))  # type: ignore[misc]
            written.append(out / name)
        except OSError as exc:  # pyarrow's own errors on a full disk are OSErrors too
            failed[name] = getattr(exc, "strerror", None) or str(exc).splitlines()[0]
    return written, failed


def _column(values: list[Any]) -> Any:
    """One column with one type: bool, int64, float64 (ints among floats), else text (JSON for the rest)."""
    import pyarrow as pa

    present = [v for v in values if v is not None]
    if present and all(isinstance(v, bool) for v in present):
        return pa.array(values, pa.bool_())
    if present and all(isinstance(v, int) and not isinstance(v, bool) for v in present):
        return pa.array(values, pa.int64())
    if present and all(isinstance(v, int | float) and not isinstance(v, bool) for v in present):
        return pa.array([None if v is None else float(v) for v in values], pa.float64())
    return pa.array([None if v is None else v if isinstance(v, str) else json.dumps(v) for v in values], pa.string())
