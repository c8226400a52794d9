"""Judged claims written out: the report's claims table (folded to the terminal), ``claims.json`` and the
Markdown tables of the documentation (``fleet sweep claims-md``), all from the same :class:`Judged` values.

``claims.json`` is a list with one entry per claim and setting (``beside``'s value): ``claim``, ``criterion``,
``where``, ``figure`` (what the number is), ``value``, ``ci`` (``[low, high]``), ``level``, ``n`` (replicates),
``verdict``, ``replicates_needed`` (for an undecided claim), ``parts`` (each figure of the claim, with the same
keys) and ``bootstrap`` (method, resamples, seed); after ``--until-decided``, ``look`` (which look decided it).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from fleet_emu.sweep.claims import Judged, Part, _num
from fleet_emu.sweep.intervals import Bootstrap, Verdict, level_text

STYLE = {Verdict.REPRODUCED: "green", Verdict.NOT_REPRODUCED: "red", Verdict.INCONCLUSIVE: "yellow",
         Verdict.TOO_FEW: "dim", Verdict.NO_DATA: "dim", Verdict.NOT_JUDGED: "dim"}
METHOD = "bootstrap over replicates, expanded percentile (Hesterberg 2015)"


def ci_text(p: Part) -> str:
    """``[low, high]``, or ``-`` without one."""
    iv = p.interval
    return "-" if math.isnan(iv.low) else f"[{_num(iv.low)}, {_num(iv.high)}]"


def verdict_text(v: Verdict, needed: int | None) -> str:
    return f"{v} (needs ~{needed})" if v in (Verdict.INCONCLUSIVE, Verdict.TOO_FEW) and needed else str(v)


def rows(judged: list[Judged]) -> list[list[str]]:
    """The claims table's cells: claim, setting, criterion, figure, value, interval, n, verdict; a claim of
    several figures gets a line per figure and a last line with the claim's verdict."""
    out = []
    for j in judged:
        setting = ", ".join(f"{k} = {_num(v)}" for k, v in j.where.items())
        head = [j.claim.text, setting, j.claim.criterion()]
        if not j.parts:
            out.append([*head, "", "", "", "", str(j.verdict)])
            continue
        for i, p in enumerate(j.parts):
            label = f"{p.label}: {p.figure}" if p.label else p.figure
            out.append([*(head if i == 0 else ["", "", ""]), label, _num(p.interval.value), ci_text(p),
                        str(p.interval.n), verdict_text(p.verdict, p.needed)])
        if len(j.parts) > 1:
            main = j.main
            out.append(["", "", "", "the claim", "", "", "", verdict_text(j.verdict, main.needed if main else None)])
    return out


def table(judged: list[Judged], source: str, level: float) -> Any:
    """The rich table: the claim's words fold, the numbers do not."""
    from rich.table import Table

    beside = any(j.where for j in judged)
    t = Table(title=f"the paper's claims, judged on ours ({level_text(level)} intervals over replicates) — {source}")
    t.add_column("claim", ratio=3, overflow="fold")
    if beside:
        t.add_column("setting", ratio=1)
    t.add_column("criterion", ratio=2, overflow="fold")
    t.add_column("figure", ratio=2, overflow="fold")
    for col in ("value", f"{level_text(level)} CI", "n"):
        t.add_column(col, justify="right", no_wrap=True)
    t.add_column("verdict", ratio=1)
    for cells in rows(judged):
        verdict = cells[-1]
        style = next((s for v, s in STYLE.items() if verdict.startswith(str(v))), "")
        shown = cells if beside else cells[:1] + cells[2:]
        t.add_row(*shown[:-1], f"[{style}]{verdict}[/]" if style else verdict)
    return t


def entry(j: Judged, boot: Bootstrap, level: float) -> dict[str, Any]:
    """One claim under one setting as ``claims.json`` holds it."""
    main = j.main
    doc: dict[str, Any] = {"claim": j.claim.text, "criterion": j.claim.criterion(), "where": j.where}
    doc |= _part(main) if main else {"figure": None, "value": None, "ci": None, "n": 0}
    doc |= {"level": level, "verdict": str(j.verdict)}
    if main is not None and j.verdict in (Verdict.INCONCLUSIVE, Verdict.TOO_FEW):
        doc["replicates_needed"] = main.needed
    doc["parts"] = [_part(p) | {"verdict": str(p.verdict)} | ({"replicates_needed": p.needed} if p.needed else {})
                    for p in j.parts]
    doc["bootstrap"] = {"method": METHOD, "resamples": boot.resamples, "seed": boot.seed}
    return doc


def _part(p: Part) -> dict[str, Any]:
    iv = p.interval
    return {"label": p.label, "figure": p.figure, "value": _finite(iv.value),
            "ci": None if math.isnan(iv.low) else [_finite(iv.low), _finite(iv.high)], "n": iv.n}


def _finite(x: float) -> float | None:
    return round(float(x), 6) if math.isfinite(x) else None


def write_json(entries: list[dict[str, Any]], path: Path) -> Path:
    """``claims.json``: written whole, then renamed into place (a link planted there is replaced, not
    followed)."""
    from fleet_emu.core.files import write_atomic

    text = json.dumps(entries, indent=1, ensure_ascii=False) + "\n"
    write_atomic(path, lambda tmp: tmp.write_text(text))
    return path


def markdown(entries: list[dict[str, Any]]) -> str:
    """A claims table in Markdown from ``claims.json``'s entries (the documentation's tables)."""
    lines = ["| claim | criterion | value | interval | n | verdict |", "| --- | --- | --- | --- | --- | --- |"]
    for e in entries:
        setting = "".join(f" ({k} = {_num(v)})" for k, v in e.get("where", {}).items())
        parts = e.get("parts") or []
        value = "; ".join(f"{p['label']}: {_num(p['value'])}" if p["label"] else _num(p["value"]) for p in parts)
        ci = "; ".join(_ci(p.get("ci")) for p in parts)
        n = "; ".join(str(p["n"]) for p in parts) if len({p["n"] for p in parts}) > 1 else str(e.get("n", 0))
        verdict = e["verdict"] + (f" (needs ~{e['replicates_needed']})" if e.get("replicates_needed") else "")
        lines.append(f"| {e['claim']}{setting} | {e['criterion']} | {value or '-'} | {ci or '-'} | {n} | "
                     f"**{verdict}** |")
    return "\n".join(lines) + "\n"


def _ci(ci: list[float | None] | None) -> str:
    return "-" if not ci or ci[0] is None else f"[{_num(ci[0])}, {_num(ci[1])}]"
