"""Where a robot's decode goes: the inboxes of a fleet recorded, then heard again stage by stage.

    python -m benchmarks.hearing [--robots 100] [--ticks 60] [--cells 512] [--map maze] [--sample 0.06]
                                 [--repeat 10] [--seed 0]

The memory engine steps ``benchmarks/brain_step.py``'s fleet (``benchmarks/scale.py``'s scenario: minpos, the wall
radio, 10 % loss, map sync on), each robot hearing its own copy of what netem delivers, as over Zenoh. A share
``--sample`` of the robot-ticks after tick 0, drawn with ``random.Random(--seed)``, keeps the robot's inbox and
context. Each kept inbox is then heard again ``--repeat`` times (``agents.hearing.hear``), and each payload kind's
batch split into the stages of ``core.codec.decode_many``; one row per kind, in µs of CPU per inbox
(``time.process_time``):

- ``payloads``: how many of the kind an inbox holds (mean);
- ``concatenate``: the payloads joined behind one array header;
- ``bounds``: the check that each payload is one msgpack item of its own bytes;
- ``msgspec``: msgspec's one pass over the batch;
- ``records``: the array fields viewed and the records built (a kind with arrays only);
- ``checks``: ``validate_many`` over the batch;
- ``decode_many``: all of it, as ``hear`` calls it.

The last line is ``hear`` itself per inbox, every kind and the headers included, and what of it is outside the
rows. Progress goes to stderr.
"""

from __future__ import annotations

import random
import sys
import time
from collections.abc import Callable
from typing import Any

from benchmarks import brain_step
from benchmarks._common import FittedMap, fail, fitted_maps, machine, parser

PROG = "hearing"
COLUMNS = ["payloads", "concatenate", "bounds", "msgspec", "records", "checks", "decode_many"]


def record(m: FittedMap, a: Any) -> list[tuple[list[Any], Any]]:
    """The kept inboxes (each robot's envelopes and its context) of a run of ``a.ticks`` ticks on ``m``."""
    fleet = brain_step.fleet_for(m, a.robots, a, shared=False)
    rng = random.Random(a.seed)
    kept = []
    while not fleet.done:
        for r in fleet.agents:  # each robot's own copy, as an agent process reads its rx bundle
            fleet.rx[r] = msgs = brain_step.read_rx(r, fleet.rx.get(r, ()))[0]
            if fleet.world.tick >= 1 and msgs and rng.random() < a.sample:
                kept.append((list(msgs), fleet.brains[r].ctx))
        fleet.step()
    return kept


def _cpu_us(fn: Callable[..., Any], cases: list[tuple[Any, ...]], repeat: int, inboxes: int) -> float:
    start = time.process_time()
    for _ in range(repeat):
        for case in cases:
            fn(*case)
    return (time.process_time() - start) / repeat / max(inboxes, 1) * 1e6


def stages(kind: str, inboxes: list[tuple[list[Any], Any]], repeat: int) -> dict[str, float]:
    """µs per inbox of each stage of ``decode_many`` for the payloads of ``kind`` (inboxes with two or more)."""
    from fleet_emu.core import codec

    cls = codec.Payload.REGISTRY[kind]
    form = codec._packed_form(cls)
    batches = [([e.payload for e in envs if e.payload_kind == kind], ctx) for envs, ctx in inboxes]
    batches = [(p, ctx) for p, ctx in batches if len(p) > 1]
    joined = [(codec._array_header(len(p)) + b"".join(p), ctx) for p, ctx in batches]
    items = [(codec._list_decoder(form).decode(data), ctx) for data, ctx in joined]
    got = [((codec._viewed(cls, i) if form is not cls else (i, {})), ctx) for i, ctx in items]
    n = len(inboxes)
    return {
        "payloads": sum(len(p) for p, _ in batches) / max(n, 1),
        "concatenate": _cpu_us(lambda p, c: codec._array_header(len(p)) + b"".join(p), batches, repeat, n),
        "bounds": _cpu_us(lambda d, c: codec._RAWS.decode(d), joined, repeat, n),
        "msgspec": _cpu_us(lambda d, c: codec._list_decoder(form).decode(d), joined, repeat, n),
        "records": _cpu_us(lambda i, c: codec._viewed(cls, i), items, repeat, n) if form is not cls else 0.0,
        "checks": _cpu_us(lambda g, c: cls.validate_many(g[0], c, g[1]), got, repeat, n),
        "decode_many": _cpu_us(lambda p, c: codec.decode_many(kind, p, c), batches, repeat, n),
    }


def main(argv: list[str] | None = None) -> None:
    from fleet_emu.agents.hearing import hear
    from fleet_emu.core.errors import FleetError
    from fleet_emu.core.kernels import warm_up
    from fleet_emu.core.malloc_tuning import collect_less

    p = parser("benchmarks.hearing", __doc__)
    p.add_argument("--robots", type=int, default=100)
    p.add_argument("--ticks", type=int, default=60)
    p.add_argument("--cells", type=int, default=512)
    p.add_argument("--map", default="maze")
    p.add_argument("--sample", type=float, default=0.06)
    p.add_argument("--repeat", type=int, default=10)
    p.add_argument("--sensor-cells", type=float, default=8.0)
    p.add_argument("--comm-cells", type=float, default=20.0)
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    if a.robots < 2 or a.ticks < 2 or a.cells < 8 or not 0 < a.sample <= 1 or a.repeat < 1:
        fail(PROG, "--robots must be at least 2, --ticks at least 2, --cells at least 8, --sample in (0, 1], "
                   "--repeat at least 1")
    warm_up()
    collect_less()  # an agent process's collector threshold
    (m,) = fitted_maps(PROG, [a.map], a.cells, a.seed)
    try:
        inboxes = record(m, a)
    except FleetError as exc:
        fail(PROG, f"map {m.name}: {str(exc).splitlines()[0]}")
    if not inboxes:
        fail(PROG, "no inbox was kept: raise --sample or --ticks")
    print(f"# benchmarks/hearing.py: {machine()}")
    print(f"# memory engine, {a.robots} robots, {a.ticks} ticks on {m.name}, {len(inboxes)} inboxes kept "
          f"({sum(len(e) for e, _ in inboxes) / len(inboxes):.1f} envelopes each), {a.repeat} repeats; "
          "µs of CPU per inbox")
    print(f"{'kind':>8} " + " ".join(f"{c:>11}" for c in COLUMNS), flush=True)
    batched = 0.0
    for kind in ("pose", "map"):
        row = stages(kind, inboxes, a.repeat)
        batched += row["decode_many"]
        print(f"{kind:>8} " + " ".join(f"{row[c]:>11.1f}" for c in COLUMNS), flush=True)
    whole = 0.0
    for _ in range(a.repeat):  # fresh envelopes each time: one opened alone keeps what it decoded (open_envelope)
        fresh = [(brain_step.read_rx("r", e)[0], ctx) for e, ctx in inboxes]
        whole += _cpu_us(lambda e, c: hear(e, c), fresh, 1, len(inboxes)) / a.repeat
    print(f"hear: {whole:.1f} µs per inbox, of which {whole - batched:.1f} outside the rows above (the headers, "
          "the grouping, and the kinds decoded one by one: a fill, an allocator's messages)")
    print(f"{m.name}: {len(inboxes)} inboxes heard {a.repeat} times", file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
