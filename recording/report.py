"""``fleet report``: metrics, plots and a table from a recording alone.

The scenario comes from the MCAP's ``scenario`` metadata; :class:`.metrics.RunMetrics` folds the recorded
msgpack messages (the same monitor fold as the live run, so the recomputed ``result.json`` keys are equal). The
file is read sequentially with the mcap package's stream reader, so a recording without summary or footer (the
launcher was killed) reads up to its last complete chunk: the recorder flushes one at least once a second.

Writes ``metrics.json`` and ``coverage.png``, ``connectivity.png``, ``map.png``, ``messages.png`` beside the
recording (prefixed with the recording's name when it is not ``run.mcap``). ``--compare`` puts several runs in one
table and overlays their coverage curves in one PNG.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from mcap.records import Channel, Metadata
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader
from rich.console import Console
from rich.table import Table

from fleet_emu.core.errors import ReportError
from fleet_emu.recording.metrics import RunMetrics

MAGIC = b"\x89MCAP0\r\n"
PLOTS = ("coverage", "connectivity", "map", "messages")


class Run:
    """One recording, read and folded."""

    def __init__(self, path: Path, metrics: RunMetrics, messages: int, truncated: bool) -> None:
        self.path = path
        self.fold = metrics
        self.messages = messages
        self.truncated = truncated
        self.metrics = metrics.metrics(str(path))
        self.metrics["recording"]["messages"] = messages
        self.metrics["truncated"] = truncated  # the recording was cut (no summary): read up to its last chunk

    @property
    def name(self) -> str:
        return self.path.parent.name if self.path.name == "run.mcap" else self.path.stem

    @property
    def label(self) -> str:
        return f"{self.name} ({self.metrics['allocator']}, {self.metrics['robots']} robots)"


def resolve(path: Path) -> Path:
    """RUN_DIR (holding run.mcap) or RUN.mcap -> the recording's path."""
    if path.is_dir():
        mcap = path / "run.mcap"
        if not mcap.is_file():
            raise ReportError(f"{path} holds no run.mcap")
        return mcap
    if not path.exists():
        raise ReportError(f"no such file or directory: {path}")
    if not path.is_file():
        raise ReportError(f"not a file: {path}")
    return path


def read_run(path: Path) -> Run:
    """Read and fold one recording (RUN_DIR or RUN.mcap); tolerates a cut last chunk."""
    mcap = resolve(Path(path))
    try:
        f = open(mcap, "rb")  # noqa: SIM115 (closed below)
    except OSError as exc:
        raise ReportError(f"cannot read {mcap}: {exc.strerror or exc}") from None
    with f:
        if f.read(len(MAGIC)) != MAGIC:
            raise ReportError(f"{mcap} is not an MCAP file")
        f.seek(0)
        size = mcap.stat().st_size
        channels: dict[int, Channel] = {}
        pending: list[tuple[str, bytes, int]] = []
        fold: RunMetrics | None = None
        messages = 0
        truncated = False
        records = StreamReader(f, record_size_limit=max(size, 1)).records
        while True:
            try:
                rec = next(records)
            except StopIteration:
                break
            except Exception:  # the file ends inside a record (a cut recording): keep what was read
                truncated = True
                break
            if isinstance(rec, McapMessage):
                messages += 1
                ch = channels.get(rec.channel_id)
                if ch is None or ch.message_encoding != "msgpack":
                    continue
                if fold is None:
                    pending.append((ch.topic, rec.data, rec.publish_time))
                else:
                    fold.feed(ch.topic, rec.data, rec.publish_time)
            elif isinstance(rec, Channel):
                channels.setdefault(rec.id, rec)
            elif isinstance(rec, Metadata) and rec.name == "scenario" and fold is None:
                fold = _fold_for(rec.metadata, mcap)
                for item in pending:
                    fold.feed(*item)
                pending.clear()
    if fold is None:
        if truncated and not messages:
            raise ReportError(f"{mcap} was cut before anything was flushed to it")
        raise ReportError(f"{mcap} has no 'scenario' metadata: not a fleet recording")
    return Run(mcap, fold, messages, truncated)


def _fold_for(metadata: dict[str, str], mcap: Path) -> RunMetrics:
    try:
        scenario = json.loads(metadata["scenario"])
        run_id = metadata.get("run_id", "")
        return RunMetrics(scenario, run_id)
    except (KeyError, ValueError, TypeError) as exc:
        raise ReportError(f"{mcap}: unreadable scenario metadata ({exc})") from None


def output_paths(mcap: Path) -> dict[str, Path]:
    prefix = "" if mcap.name == "run.mcap" else mcap.stem + "."
    out = {"metrics": mcap.parent / f"{prefix}metrics.json"}
    out |= {p: mcap.parent / f"{prefix}{p}.png" for p in PLOTS}
    return out


def write_report(run: Run, plots: bool = True) -> dict[str, Path]:
    """metrics.json and the PNGs beside the recording; returns their paths."""
    paths = output_paths(run.path)
    paths["metrics"].write_text(json.dumps(run.metrics, indent=2))
    if plots:
        coverage_plot(run, paths["coverage"])
        connectivity_plot(run, paths["connectivity"])
        map_plot(run, paths["map"])
        messages_plot(run, paths["messages"])
    else:
        for p in PLOTS:
            paths.pop(p)
    return paths


def _fmt(v: Any, pct: bool = False) -> str:
    if v is None:
        return "-"
    if pct:
        return f"{v:.1%}"
    if isinstance(v, float):
        return f"{v:.3g}" if abs(v) < 1000 else f"{v:.0f}"
    return str(v)


def _each(values: dict[str, Any], pct: bool = False) -> str:
    return ", ".join(f"{k} {_fmt(v, pct)}" for k, v in values.items())


def summary_table(run: Run) -> Table:
    m = run.metrics
    t = Table(title=f"report {m['run_id']}  [dim]{run.path}[/dim]", show_header=False, title_justify="left")
    t.add_column("metric", style="bold")
    t.add_column("value")
    et, rd, conn, dt, sh = m["exploration_time"], m["radio_detail"], m["connectivity"], m["decision_time"], m["share"]
    pairs = _each(conn["pair_link_fraction"], pct=True)
    per_robot = rd["per_robot"]
    rows = [
        ("map / allocator", f"{m['map']} / {m['allocator']}"),
        ("robots / seed", f"{m['robots']} / {m['seed']}"),
        ("radio", f"{m['comm']}, loss {m['loss']}"),
        ("completed", f"{m['completed']} ({m['reason']})" + ("  [yellow]recording cut[/yellow]"
                                                            if m.get("truncated") else "")),
        ("coverage", _fmt(m["coverage"], True)),
        ("ticks", str(m["ticks"])),
        ("t90 / t99 / t100", f"{_fmt(et['t90'])} / {_fmt(et['t99'])} / {_fmt(et['t100'])}"),
        ("path length", f"{m['path']['total']} cells ({_each(m['path']['per_robot'])})"),
        ("efficiency", f"{_fmt(m['efficiency']['value'])} free cells sensed per cell travelled"),
        ("overlap", f"{m['overlap']['cells']} cells sensed by 2+ robots ({_fmt(m['overlap']['fraction'], True)})"),
        ("share (first sensed)", _each(sh["share"], pct=True)),
        ("evenness", f"Jain {_fmt(sh['jain'])}, Gini {_fmt(sh['gini'])}"),
        ("connected", _fmt(m["connected_fraction"], True)),
        ("link time per pair", pairs or "-"),
        ("radio msgs", f"sent {rd['sent']}, delivered {rd['delivered']}, lost {rd['dropped']['loss']}, "
                       f"out of range {rd['dropped']['signal']}"),
        ("tx bytes/robot/tick", f"{_fmt(rd['bytes_per_robot_per_tick'])} "
                                f"({_each({r: v['bytes_per_tick'] for r, v in per_robot.items()})})"),
        ("decision ms", f"mean {_fmt(dt['mean_ms'])}, p50 {_fmt(dt['p50_ms'])}, p95 {_fmt(dt['p95_ms'])}, "
                        f"max {_fmt(dt['max_ms'])} ({dt['calls']} calls)"),
        ("recording", f"{m['recording']['messages']} messages"),
    ]
    for k, v in rows:
        t.add_row(k, v)
    return t


COMPARE_ROWS = (
    ("map", lambda m: m["map"]),
    ("allocator", lambda m: m["allocator"]),
    ("robots", lambda m: m["robots"]),
    ("radio", lambda m: f"{m['comm']}, loss {m['loss']}"),
    ("completed", lambda m: f"{m['completed']} ({m['reason']})"),
    ("coverage", lambda m: _fmt(m["coverage"], True)),
    ("ticks", lambda m: m["ticks"]),
    ("t90", lambda m: _fmt(m["exploration_time"]["t90"])),
    ("t99", lambda m: _fmt(m["exploration_time"]["t99"])),
    ("t100", lambda m: _fmt(m["exploration_time"]["t100"])),
    ("path", lambda m: m["path"]["total"]),
    ("efficiency", lambda m: _fmt(m["efficiency"]["value"])),
    ("overlap", lambda m: _fmt(m["overlap"]["fraction"], True)),
    ("Jain", lambda m: _fmt(m["share"]["jain"])),
    ("connected", lambda m: _fmt(m["connected_fraction"], True)),
    ("delivered", lambda m: _fmt(m["radio_detail"]["delivered_fraction"], True)),
    ("B/robot/tick", lambda m: _fmt(m["radio_detail"]["bytes_per_robot_per_tick"])),
    ("decision ms", lambda m: _fmt(m["decision_time"]["mean_ms"])),
)


def compare_table(runs: list[Run]) -> Table:
    """One row per metric, one column per run (readable in a terminal for a handful of runs)."""
    t = Table(title="comparison", title_justify="left")
    t.add_column("metric", style="bold")
    for run in runs:
        t.add_column(run.name, justify="right", overflow="fold")
    t.add_row("run id", *(str(run.metrics["run_id"]) for run in runs))
    for name, get in COMPARE_ROWS:
        t.add_row(name, *(str(get(run.metrics)) for run in runs))
    return t


def report(paths: list[Path], compare: bool = False, out: Path | None = None, plots: bool = True,
           console: Console | None = None) -> list[Run]:
    """What ``fleet report`` does; raises ReportError on bad input."""
    console = console or Console()
    if out is not None and not compare:
        raise ReportError("--out goes with --compare (a single report is written beside its recording)")
    runs = [read_run(p) for p in paths]
    if compare:
        out = out or Path("compare.png")
        if out.is_dir():
            out = out / "compare.png"
        if not out.parent.exists():
            raise ReportError(f"no such directory: {out.parent}")
        console.print(compare_table(runs))
        compare_plot(runs, out)
        console.print(f"coverage curves: {out}")
        return runs
    for run in runs:
        written = write_report(run, plots=plots)
        console.print(summary_table(run))
        console.print("wrote " + ", ".join(str(p) for p in written.values()))
        if run.truncated:
            console.print(f"[yellow]{run.path} was cut (no summary): read up to its last complete chunk[/yellow]")
        _check_result(run, console)
    return runs


def _check_result(run: Run, console: Console) -> None:
    """Where the live result.json sits beside the recording, say whether the recomputed values agree."""
    live = run.path.parent / "result.json"
    if run.path.name != "run.mcap" or not live.is_file():
        return
    try:
        res = json.loads(live.read_text())
    except (OSError, ValueError):
        return
    diff = differences(res, run.metrics)
    if diff:
        console.print(f"[yellow]differs from result.json: {', '.join(diff)}[/yellow]")
    else:
        console.print("[green]matches result.json[/green]")


def differences(result: dict[str, Any], metrics: dict[str, Any]) -> list[str]:
    """Keys of a live result.json whose values the recomputed metrics do not reproduce."""
    skip = {"wall_seconds", "pids"}  # the launcher's clock and process ids are not on the bus
    out = []
    for k, v in result.items():
        if k in skip:
            continue
        w = metrics.get(k)
        if k == "recording":
            v, w = (v or {}).get("messages"), (w or {}).get("messages")
        if not _same(v, w):
            out.append(k)
    return out


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) or isinstance(b, float):
        return a is not None and b is not None and bool(np.isclose(a, b, rtol=0, atol=1e-9))
    return a == b


# --- plots (matplotlib, Agg: no display needed) ----------------------------------------------------------------

def _figure(rows: int = 1, height: float = 3.6) -> tuple[Any, Any]:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, height * rows if rows > 1 else height), dpi=110, layout="constrained")
    axes = fig.subplots(rows, 1, sharex=True) if rows > 1 else fig.subplots()
    return fig, axes


def _curve(run: Run) -> tuple[np.ndarray, np.ndarray]:
    curve = sorted(dict(run.fold.monitor.coverage_curve).items())
    return np.array([t for t, _ in curve], dtype=float), np.array([c for _, c in curve], dtype=float)


def coverage_plot(run: Run, path: Path) -> None:
    fig, ax = _figure()
    t, c = _curve(run)
    ax.plot(t, 100 * c, color="tab:blue", lw=2, label="team coverage")
    target = run.fold.scenario.get("target_coverage", 0.99)
    for level, style in ((0.9, ":"), (0.99, "--")):
        ax.axhline(100 * level, color="grey", ls=style, lw=1)
    et = run.metrics["exploration_time"]
    for key, label in (("t90", "90 %"), ("t99", "99 %"), ("t100", "100 %")):
        if et[key] is not None:
            ax.axvline(et[key], color="tab:red", ls=":", lw=1)
            ax.annotate(f"{label} @ {et[key]}", (et[key], 5), rotation=90, fontsize=8, color="tab:red",
                        xytext=(3, 0), textcoords="offset points")
    ax.set(xlabel="tick", ylabel="coverage (%)", ylim=(0, 102),
           title=f"coverage: {run.label}, target {target:.0%}")
    ax.grid(alpha=0.3)
    fig.savefig(path)


def connectivity_plot(run: Run, path: Path) -> None:
    """Like Benavides et al. Figs. 6-8: connected or not, links, and the mean signal, per tick."""
    s = run.fold.series
    fig, (a1, a2, a3) = _figure(3, 1.6)
    t, conn = s.arrays("connected")
    a1.fill_between(t, conn, step="post", color="tab:green", alpha=0.5)
    a1.set(ylabel="connected", ylim=(-0.05, 1.05), yticks=[0, 1], yticklabels=["no", "yes"],
           title=f"connectivity: {run.label}, connected {_fmt(run.metrics['connected_fraction'], True)}")
    t, links = s.arrays("links")
    n = len(run.fold.robots)
    a2.step(t, links, where="post", color="tab:blue")
    a2.set(ylabel="links", ylim=(-0.2, max(1, n * (n - 1) / 2) + 0.2))
    t, db = s.arrays("strength")
    a3.plot(t, db, color="tab:purple", lw=1)
    a3.axhline(float(run.fold.scenario.get("radio", {}).get("threshold", 0.0)), color="grey", ls="--", lw=1)
    a3.set(ylabel="mean P (dB)", xlabel="tick")
    for a in (a1, a2, a3):
        a.grid(alpha=0.3)
    fig.savefig(path)


def map_plot(run: Run, path: Path) -> None:
    """The team's final map (what the robots sensed, true values) with each robot's trajectory."""
    from fleet_emu.recording.foxglove import robot_rgb

    f = run.fold
    fig, ax = _figure(height=5.5)
    if f.team is not None:
        g = f.team.value.reshape(f.team.shape)
        img = np.full((*f.team.shape, 3), 0.72)
        img[g == 0] = 1.0
        img[g > 0] = 0.1
        ax.imshow(img, interpolation="nearest")
    failed = set(run.metrics.get("failed") or [])
    for r, traj in f.trajectory.items():
        if not traj:
            continue
        rows = [c[0] for _, c in traj]
        cols = [c[1] for _, c in traj]
        color = robot_rgb(r, f.robots)
        ax.plot(cols, rows, color=color, lw=1.5, label=f"{r} ({run.metrics['path']['per_robot'][r]} cells)")
        ax.plot(cols[0], rows[0], "o", color=color, ms=6)
        ax.plot(cols[-1], rows[-1], "x" if r in failed else "s", color=color, ms=7)
    ax.set(title=f"final map and trajectories: {run.label}", xlabel="column", ylabel="row")
    ax.legend(fontsize=7, loc="upper right")
    fig.savefig(path)


def messages_plot(run: Run, path: Path) -> None:
    s = run.fold.series
    fig, ax = _figure()
    t, tx = s.arrays("tx_msgs")
    ax.plot(t, tx, color="tab:blue", lw=1, label="sent (radio messages)")
    t, rx = s.arrays("rx_msgs")
    ax.plot(t, rx, color="tab:green", lw=1, label="delivered (per receiver)")
    ax.set(xlabel="tick", ylabel="messages per tick", title=f"radio traffic: {run.label}")
    ax2 = ax.twinx()
    t, b = s.arrays("tx_bytes")
    ax2.plot(t, b / 1024, color="tab:orange", lw=0.8, alpha=0.7, label="tx bundles (KiB)")
    ax2.set_ylabel("KiB per tick")
    lines = ax.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + lines2[0], lines[1] + lines2[1], fontsize=8, loc="upper right")
    ax.grid(alpha=0.3)
    fig.savefig(path)


def compare_plot(runs: list[Run], path: Path) -> None:
    fig, ax = _figure(height=4.2)
    for run in runs:
        t, c = _curve(run)
        ax.plot(t, 100 * c, lw=1.8, label=run.label)
    ax.axhline(90, color="grey", ls=":", lw=1)
    ax.axhline(99, color="grey", ls="--", lw=1)
    ax.set(xlabel="tick", ylabel="coverage (%)", ylim=(0, 102), title="coverage")
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(alpha=0.3)
    fig.savefig(path)
