"""Both engines publish the same messages (docs/design/architecture.md, "Engines"): one run over Zenoh and the memory
engine's run of the same scenario, both recorded, every message of ``run.mcap`` decoded and compared field by field,
for every kind, and the Foxglove channels derived from them too.

The scenario is small but has every kind the lockstep sends: a planning base station (``mhm``: the base's
tx bundles and its report), relaying and loss (envelopes in the rx bundles), belief snapshots, the start
handshake, the stop and every report. Measured values (wall and CPU times, RSS, pids) differ from run to run:
for those only the presence and type are compared (a dict: its keys, and the type of each value).
"""

from __future__ import annotations

import collections
import json
from pathlib import Path
from typing import Any

import msgspec
import numpy as np
from mcap.reader import make_reader

import fleet_emu as fe
from fleet_emu.core.codec import Message, decode
from fleet_emu.core.keys import BASE, Keys
from fleet_emu.core.messages import RobotReport, WorldState  # (and every other kind registered with the codec)

RUN_ID = "engines"

#: Fields that are measured, not computed: compared by presence and type only.
MEASURED: dict[str, frozenset[str]] = {
    "report": frozenset({"decision_ms_mean", "decision_ms_p95", "peak_rss_kb", "decision_cpu_ms", "step_cpu_ms",
                         "process_cpu_ms", "loop_cpu_ms", "stage_cpu_ms", "first_cpu_ms"}),
    "base_report": frozenset({"peak_rss_kb"}),
    "cmd": frozenset({"decision_ms"}),
    "ready": frozenset({"pid"}),
}
#: The start handshake repeats until every node answered, as timing goes: compared as sets of distinct messages.
HANDSHAKE = frozenset({"hello", "ready"})
#: The launcher's notice that a robot's process exited: in a run where none fails, sent only when the launcher
#: sees the robots exit (after their reports) before it has folded the world's stop; the memory engine has no
#: processes to lose. Left out.
TIMING_ONLY = frozenset({"failed"})
#: Every kind the scenario must show in both recordings, so that none goes unchecked.
EXPECTED = frozenset({"hello", "ready", "obs", "state", "cmd", "tx", "rx", "links", "belief", "report",
                      "base_report", "stop"})


def test_both_engines_record_the_same_messages_field_by_field(tmp_path: Path, small_map: Path) -> None:
    s = fe.Scenario().override(map=str(small_map), robots=2, allocator="mhm", base=True, loss=0.2, seed=5,
                               max_ticks=20)
    over_zenoh = fe.run(s, out=tmp_path / "p", run_id=RUN_ID)
    in_memory = fe.run(s, out=tmp_path / "m", run_id=RUN_ID, engine="memory")
    assert over_zenoh["engine"] == "processes" and in_memory["engine"] == "memory"
    procs, mem = _messages(tmp_path / "p" / "run.mcap"), _messages(tmp_path / "m" / "run.mcap")

    kinds = {msg.KIND for msgs in procs.values() for msg in msgs} - TIMING_ONLY
    assert kinds == {msg.KIND for msgs in mem.values() for msg in msgs}
    assert kinds >= EXPECTED, f"the scenario shows no {sorted(EXPECTED - kinds)}"
    keys = Keys(RUN_ID)
    assert keys.tx(BASE) in mem and keys.report(BASE) in mem  # the planning base sent and reported
    assert {k for k, msgs in procs.items() if msgs[0].KIND not in TIMING_ONLY} == set(mem)

    diffs: list[str] = []
    for key in sorted(mem):
        diffs += _compare_key(key, procs[key], mem[key])
    assert not diffs, f"{len(diffs)} differences (processes vs memory):\n" + "\n".join(diffs[:30])
    assert _foxglove(tmp_path / "p" / "run.mcap") == _foxglove(tmp_path / "m" / "run.mcap")


def test_the_comparison_sees_a_dropped_or_changed_field() -> None:
    """The comparison is not blind: a field left at its default in one engine, a measured field of another
    type, a missing message and an extra one are all reported."""
    report = dict(src="r0", tick=3, seq=9, decisions=3, decision_ms_mean=0.1, decision_ms_p95=0.2, dropped=0,
                  peak_rss_kb=1, stage_cpu_ms={"merge": 0.5}, first_cpu_ms={"step": 0.1})
    a = RobotReport(**report)
    assert _compare_key("k", [a], [msgspec.structs.replace(a, decision_ms_mean=7.0, peak_rss_kb=2)]) == []
    assert _compare_key("k", [a], [msgspec.structs.replace(a, stage_cpu_ms={})]) == [
        "k tick 3 seq 9 report.stage_cpu_ms: {'merge': 0.5} vs {}"]
    assert _compare_key("k", [a], [msgspec.structs.replace(a, decisions=2)]) == [
        "k tick 3 seq 9 report.decisions: 3 vs 2"]
    assert _compare_key("k", [a], [msgspec.structs.replace(a, peak_rss_kb=1.0)]) == [
        "k tick 3 seq 9 report.peak_rss_kb: 1 vs 1.0"]
    assert _compare_key("k", [a], []) == ["k: (tick, seq) only in processes [(3, 9)], only in memory []"]
    state = WorldState(src="world", tick=0, seq=1, poses={"r0": (1, 1)}, live=("r0",), coverage=0.5,
                       path_length={"r0": 0}, dropped=2)
    assert _compare_key("s", [state], [msgspec.structs.replace(state, dropped=0)]) == [
        "s tick 0 seq 1 state.dropped: 2 vs 0"]


def _messages(path: Path) -> dict[str, list[Message]]:
    """Every bus message of a recording, decoded, by key expression, in file order."""
    out: dict[str, list[Message]] = collections.defaultdict(list)
    with path.open("rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            if channel.message_encoding == "msgpack":
                out[channel.topic].append(decode(message.data))
    return dict(out)


def _compare_key(key: str, procs: list[Message], mem: list[Message]) -> list[str]:
    """The differences between one key's messages in the two engines: by (tick, seq), field by field."""
    if procs and procs[0].KIND in HANDSHAKE:
        a, b = _distinct(procs), _distinct(mem)
        return [] if a == b else [f"{key}: handshake {sorted(a)} vs {sorted(b)}"]
    by_p = {(m.tick, m.seq): m for m in procs}
    by_m = {(m.tick, m.seq): m for m in mem}
    assert len(by_p) == len(procs) and len(by_m) == len(mem), f"{key}: a (tick, seq) sent twice"
    if by_p.keys() != by_m.keys():
        return [f"{key}: (tick, seq) only in processes {sorted(by_p.keys() - by_m.keys())}, "
                f"only in memory {sorted(by_m.keys() - by_p.keys())}"]
    diffs = []
    for (tick, seq), p in sorted(by_p.items()):
        m = by_m[(tick, seq)]
        if type(p) is not type(m):
            diffs.append(f"{key} tick {tick} seq {seq}: {type(p).__name__} vs {type(m).__name__}")
            continue
        measured = MEASURED.get(p.KIND, frozenset())
        for field in msgspec.structs.fields(p):
            x, y = getattr(p, field.name), getattr(m, field.name)
            if not (_alike(x, y) if field.name in measured else _same(x, y)):
                diffs.append(f"{key} tick {tick} seq {seq} {p.KIND}.{field.name}: {_show(x)} vs {_show(y)}")
    return diffs


def _distinct(msgs: list[Message]) -> set[str]:
    """A handshake key's distinct messages, measured fields left out."""
    measured = MEASURED.get(msgs[0].KIND, frozenset()) if msgs else frozenset()
    return {repr({f.name: getattr(m, f.name) for f in msgspec.structs.fields(m) if f.name not in measured})
            for m in msgs}


def _same(a: Any, b: Any) -> bool:
    """Equal values of equal types, arrays (dtype and shape too) and nested messages (envelopes) included."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.dtype == b.dtype
                and a.shape == b.shape and bool(np.array_equal(a, b)))
    if isinstance(a, msgspec.Struct):
        return type(a) is type(b) and all(_same(getattr(a, f), getattr(b, f)) for f in a.__struct_fields__)
    if isinstance(a, tuple | list):
        return type(a) is type(b) and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return type(b) is dict and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return type(a) is type(b) and a == b


def _alike(a: Any, b: Any) -> bool:
    """A measured value: present with the same type (a dict: the same keys, each value of the same type)."""
    if isinstance(a, dict):
        return type(b) is dict and a.keys() == b.keys() and all(type(a[k]) is type(b[k]) for k in a)
    return type(a) is type(b)


def _show(v: Any) -> str:
    text = repr(v.tolist() if isinstance(v, np.ndarray) else v)
    return text if len(text) <= 120 else text[:117] + "..."


def _foxglove(path: Path) -> dict[str, list[Any]]:
    """The Foxglove channels (JSON), by topic in file order, the robots' decision times (measured) left out, and
    every time taken from the run's start (the recording's ``start_ns``: the one thing two runs of a seed differ
    by)."""
    out: dict[str, list[Any]] = collections.defaultdict(list)
    with path.open("rb") as f:
        reader = make_reader(f)
        start = int(next(m.metadata["start_ns"] for m in reader.iter_metadata() if m.name == "scenario"))
        f.seek(0)
        for _schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            if channel.message_encoding == "json":
                out[channel.topic].append((message.log_time - start, _unmeasured(json.loads(message.data), start)))
    return dict(out)


def _unmeasured(obj: Any, start: int) -> Any:
    if isinstance(obj, dict):
        if obj.keys() == {"sec", "nsec"}:  # a Foxglove time: from the run's start
            return obj["sec"] * 10**9 + obj["nsec"] - start
        return {k: v if k == "lifetime" else _unmeasured(v, start) for k, v in obj.items() if k != "decision_ms"}
    if isinstance(obj, list):
        return [_unmeasured(v, start) for v in obj if not (isinstance(v, dict) and v.get("key") == "decision_ms")]
    return obj
