"""``fleet sweep STUDY --until-decided [--max-seeds N]``: run a study's replicates, then more in batches, until
every claim is decided (reproduced or not) or the cap is reached.

The batches double the replicates (the study's seeds, or the values of the grid key a study names as its
replicate with ``[study] more``, e.g. more start cells) up to the cap: looks at n, 2n, 4n ... and the cap. Looking
at the intervals after each batch and stopping when they decide would make a 95 % interval cover less than 95 %
of the time over the whole procedure, so every look uses the level ``1 - (1 - level) / K`` for the K planned
looks: Bonferroni's alpha spending, the simplest schedule that keeps the overall error rate at most the stated
one whatever the looks show (Jennison & Turnbull 2000, *Group Sequential Methods with Applications to Clinical
Trials*, sections 1.3 and 7.2). A claim is judged at the first look that decides it; the others at the last.

The plan and what each look decided are kept in ``decided.json`` beside the results, so that ``fleet sweep
report`` judges each claim as the look that decided it did, and a second call resumes.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from fleet_emu.core.errors import ConfigError
from fleet_emu.sweep.claims import Judged, evaluate
from fleet_emu.sweep.intervals import Bootstrap, Verdict, level_text

DECIDED = "decided.json"
#: Verdicts that more replicates may still change.
OPEN = (Verdict.INCONCLUSIVE, Verdict.TOO_FEW)


def looks(first: int, cap: int) -> list[int]:
    """The replicate counts looked at: ``first``, doubled each time, and ``cap`` (``first`` alone when the cap
    is not above it)."""
    out = [first]
    while out[-1] < cap:
        out.append(min(cap, out[-1] * 2))
    return out


def look_level(level: float, planned: int) -> float:
    """The level each of ``planned`` looks uses so that all of them hold together at ``level`` (Bonferroni)."""
    return 1.0 - (1.0 - level) / planned


@dataclasses.dataclass(frozen=True)
class Plan:
    """The sequential plan of a study: the replicate axis (``seed`` or a grid key), its values in order, the
    counts looked at and the overall level."""

    axis: str
    values: list[Any]
    counts: list[int]
    level: float

    @property
    def per_look(self) -> float:
        return look_level(self.level, len(self.counts))

    def rows_of(self, rows: list[dict[str, Any]], look: int) -> list[dict[str, Any]]:
        """The rows of the first ``counts[look]`` replicates."""
        from fleet_emu.sweep.figures import key

        keep = {key(v) for v in self.values[:self.counts[look]]}
        return [r for r in rows if key(r.get(f"param.{self.axis}")) in keep]


def plan(study: Any, cap: int | None, level: float) -> Plan:
    """A study's plan: its seeds grown to ``cap`` (default 4 x its seeds), or the replicate key its ``more``
    table grows (default: every value listed)."""
    if study.more:
        (axis, extra), = study.more.items()
        values = [*study.grid[axis], *extra]
    else:
        axis = "seed"
        values = list(study.seeds)
        nxt = max(values) + 1
        while len(values) < (cap or 4 * len(study.seeds)):
            values.append(nxt)
            nxt += 1
    first = len(study.grid[axis]) if study.more else len(study.seeds)
    top = len(values) if cap is None else cap
    if top < first:
        raise ConfigError(f"--max-seeds must be at least the study's {first} replicates (got {top})")
    if top > len(values):
        raise ConfigError(f"--max-seeds {top}: study {study.name} lists {len(values)} values of {axis} to grow by "
                          f"([study] more)")
    return Plan(axis, values[:top], looks(first, top), level)


def grown(study: Any, p: Plan, look: int) -> Any:
    """The study with the replicates of a look."""
    vals = p.values[:p.counts[look]]
    if p.axis == "seed":
        return dataclasses.replace(study, seeds=vals)
    return dataclasses.replace(study, grid=study.grid | {p.axis: vals})


def until_decided(study: Any, out: Path, run: Callable[[Any], int], cap: int | None, boot: Bootstrap,
                  say: Callable[[str], None]) -> int:
    """Run the looks of the plan (``run(grown study)`` runs its points, resuming; its exit code), stopping when
    every claim is decided; the exit code of the last look (an interrupted or full-disk look stops at once)."""
    from fleet_emu.sweep.execute import read_rows

    p = plan(study, cap, boot.level)
    say(f"{study.name}: until decided, {p.axis} in batches of {' → '.join(map(str, p.counts))} replicates; "
        f"{len(p.counts)} looks at {level_text(p.per_look)} each keep {level_text(p.level)} over all of them "
        f"(Bonferroni)")
    decided: dict[str, int] = {}
    code = 0
    for k in range(len(p.counts)):
        code = run(grown(study, p, k))
        if code in (1, 130, 143):  # the disk, Ctrl-C, SIGTERM: stop now, what ran is kept
            break
        judged = evaluate(_as_dict(study), p.rows_of(read_rows(out), k), study.baseline, boot, p.per_look)
        for j in judged:
            if _key(j) not in decided and j.verdict not in OPEN:
                decided[_key(j)] = k
        _write(out, p, decided, k)
        still = [j for j in judged if _key(j) not in decided and j.claim.kind]
        say(f"look {k + 1} of {len(p.counts)}: {p.counts[k]} replicates; "
            f"{len(judged) - len(still)} of {len(judged)} claims decided")
        if not still:
            break
    return code


def judged_as_decided(study: dict[str, Any], rows: list[dict[str, Any]], baseline: str | None, out: Path,
                      boot: Bootstrap) -> tuple[list[Judged], list[dict[str, Any]], float, str]:
    """The claims as the report shows them: each at the look that decided it (``decided.json``), else on every
    row at ``boot.level``; their ``claims.json`` entries, the level the table shows and a line on the plan."""
    from fleet_emu.sweep import verdicts

    kept = _read(out)
    if kept is None:
        judged = evaluate(study, rows, baseline, boot)
        return judged, [verdicts.entry(j, boot, boot.level) for j in judged], boot.level, ""
    p = Plan(kept["axis"], kept["values"], kept["counts"], kept["level"])
    last = int(kept["last_look"])
    per = [evaluate(study, p.rows_of(rows, k), baseline, boot, p.per_look) for k in range(last + 1)]
    judged, entries = [], []
    for i, j in enumerate(per[0]):
        k = int(kept["decided"].get(_key(j), last))
        judged.append(per[k][i])
        entries.append(verdicts.entry(per[k][i], boot, p.per_look) | {"look": k + 1, "replicates": p.counts[k]})
    note = (f"until decided: {p.axis}, looks at {', '.join(map(str, p.counts[:last + 1]))} replicates, each at "
            f"{level_text(p.per_look)} ({level_text(p.level)} over {len(p.counts)} planned looks, Bonferroni); a "
            f"claim is judged at the look that decided it (n)")
    return judged, entries, p.per_look, note


def _key(j: Judged) -> str:
    """A claim under a setting as ``decided.json`` names it: its words, and the setting."""
    return j.claim.text + "".join(f" | {k} = {v}" for k, v in j.where.items())


def _as_dict(study: Any) -> dict[str, Any]:
    """What :func:`evaluate` reads of a study."""
    return {"study": {"name": study.name, "replicates": list(study.replicates)}, "grid": study.grid,
            "paper": study.paper}


def _write(out: Path, p: Plan, decided: dict[str, int], last: int) -> None:
    doc = {"axis": p.axis, "values": p.values, "counts": p.counts, "level": p.level, "per_look": p.per_look,
           "decided": decided, "last_look": last}
    from fleet_emu.core.files import write_json

    write_json(out / DECIDED, doc)


def _read(out: Path) -> dict[str, Any] | None:
    from fleet_emu.core.files import read_regular

    path = out / DECIDED
    if not path.is_file() or path.is_symlink():
        return None
    try:
        doc = json.loads(read_regular(path, 16 << 20))
        ok = (isinstance(doc, dict) and isinstance(doc.get("counts"), list) and isinstance(doc.get("values"), list)
              and isinstance(doc.get("decided"), dict) and 0 < float(doc.get("level", 0)) < 1
              and 0 <= int(doc.get("last_look", -1)) < len(doc["counts"]))
    except (OSError, ValueError, TypeError):
        ok = False
    if not ok:
        raise ConfigError(f"{path} is not a plan this version wrote (remove it to judge every row at once)")
    return doc
