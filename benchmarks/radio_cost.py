"""What a bandwidth-limited radio costs the memory engine, measured inside each run.

    python -m benchmarks.radio_cost [--seeds 3] [--bandwidths 1000 64 16] [--max-ticks 3000]

Runs ``engine_speed``'s two office scenarios (3 robots minpos on the wall radio at 10 % loss; 4 robots trade on
the full radio at 30 % loss) at each bandwidth, and times the code a limited radio adds, with this process's CPU
clock around each call: the senders' queues and the media (``Medium.enqueue`` with the envelopes already
encoded, which an unlimited radio does too, and ``Medium.serve``), the compact form of map data
(``compact``) and its expansion (``unpack_payload`` of compact payloads). Prints, per bandwidth, that CPU time,
the rest of the runs' CPU time (the probe's own cost taken out), and their ratio: how much longer a run takes
than it would without the radio's bookkeeping. A ratio within one run is steadier than two runs' times
compared on a machine whose speed drifts (``engine_speed --memory-only`` between bandwidths also compares
runs that unfold differently).
"""

from __future__ import annotations

import functools
import sys
import time
from collections.abc import Callable
from typing import Any

from benchmarks._common import fail, machine, parser

SCENARIOS = ({"robots": 3, "allocator": "minpos"},
             {"robots": 4, "allocator": "trade", "comm": "full", "loss": 0.3})


class Probe:
    """CPU seconds spent in the wrapped functions, and how many calls."""

    def __init__(self) -> None:
        self.cpu = 0.0
        self.calls = 0

    def wrap(self, fn: Callable[..., Any], before: Callable[..., Any] | None = None,
             when: Callable[..., bool] | None = None) -> Callable[..., Any]:
        @functools.wraps(fn)
        def timed(*args: Any) -> Any:
            if before is not None:
                before(*args)
            if when is not None and not when(*args):
                return fn(*args)
            t = time.process_time()
            try:
                return fn(*args)
            finally:
                self.cpu += time.process_time() - t
                self.calls += 1
        return timed


def _encode_first(_medium: Any, _tick: int, bundles: dict[str, Any]) -> None:
    for msgs in bundles.values():
        for env in msgs:
            env.encode()  # kept on the envelope: the unlimited radio encodes each one too, to count its bytes


def _probe_cost() -> float:
    """CPU seconds of one pair of clock reads."""
    t = time.process_time()
    for _ in range(20000):
        time.process_time()
        time.process_time()
    return (time.process_time() - t) / 20000


def install(probe: Probe) -> None:
    """Wrap the limited radio's own code (this process only)."""
    from fleet_emu.core import envelope
    from fleet_emu.netem.medium import Medium

    wrapped = {(envelope, "compact"): probe.wrap(envelope.compact),  # seal looks it up at each call
               (envelope, "unpack_payload"): probe.wrap(envelope.unpack_payload,
                                                        when=lambda p: bool(p) and p[0] == 0x78),
               (Medium, "enqueue"): probe.wrap(Medium.enqueue, before=_encode_first),
               (Medium, "serve"): probe.wrap(Medium.serve)}
    for (owner, name), fn in wrapped.items():
        setattr(owner, name, fn)

def main(argv: list[str] | None = None) -> int:
    p = parser("benchmarks.radio_cost", __doc__)
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--bandwidths", type=float, nargs="+", default=[1000.0, 64.0, 16.0])
    p.add_argument("--max-ticks", type=int, default=3000)
    a = p.parse_args(argv)
    if a.seeds < 1 or any(b <= 0 for b in a.bandwidths):
        fail("radio_cost", "--seeds must be at least 1 and every bandwidth above 0")
    import fleet_emu as fe

    probe = Probe()
    install(probe)
    pair = _probe_cost()
    fe.Fleet(fe.Scenario().override(max_ticks=20, bandwidth=a.bandwidths[0])).run()  # warm the kernels
    print(f"# {machine()}")
    print(f"# office, {len(SCENARIOS)} scenarios x {a.seeds} seed(s); CPU seconds of this process")
    print(f"{'kbit/s':>8} {'ticks':>7} {'calls':>7} {'radio s':>8} {'rest s':>8} {'share':>7}")
    for bw in a.bandwidths:
        probe.cpu, probe.calls, total, ticks = 0.0, 0, 0.0, 0
        for over in SCENARIOS:
            for seed in range(a.seeds):
                print(f"{bw:g} kbit/s {over['allocator']} seed {seed}", file=sys.stderr)
                s = fe.Scenario().override(seed=seed, bandwidth=bw, max_ticks=a.max_ticks, **over)
                t = time.process_time()
                ticks += fe.Fleet(s).run()["ticks"]
                total += time.process_time() - t
        radio = probe.cpu - probe.calls * pair / 2  # half a pair is inside each timed span
        rest = total - probe.cpu - probe.calls * pair / 2
        print(f"{bw:>8g} {ticks:>7} {probe.calls:>7} {radio:>8.3f} {rest:>8.3f} {radio / rest:>7.1%}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
