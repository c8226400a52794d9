"""What a bandwidth-limited radio costs the memory engine, measured inside each run.

    python -m benchmarks.radio_cost [--seeds 3] [--bandwidths 1000 64 16] [--max-ticks 3000]

Runs ``engine_speed``'s two office scenarios (3 robots minpos on the wall radio at 10 % loss; 4 robots trade on
the full radio at 30 % loss) at each bandwidth, and times the code a limited radio adds, with this process's CPU
clock around each call: the senders' queues and the media (``Medium.enqueue`` with the envelopes already
encoded, which an unlimited radio does too, and ``Medium.serve``), the compact form of map data
(``compact``) and its expansion (``expand`` of compact payloads). Prints, per bandwidth, that CPU time,
the rest of the runs' CPU time (the probe's own cost taken out), and their ratio: how much longer a run takes
than it would without the radio's bookkeeping. A ratio within one run is steadier than two runs' times
compared on a machine whose speed drifts (``engine_speed --memory-only`` between bandwidths also compares
runs that unfold differently).

    python -m benchmarks.radio_cost --shadowing [--robots 16] [--seeds 3] [--max-ticks 200] [--shadowing-db 8]

instead times the correlated shadowing (``[radio] shadowing_db``, ``core/shadowing.py``): ``--robots`` robots
(minpos, the wall radio at 10 % loss, on the office), each seed once with shadowing off and once on
(``--shadowing-db`` dB, ``--shadowing-m`` m), and once as ``code only``: on, with every pair's term set to 0
after it is computed (this script's wrapper), so that all of the shadowing's code runs and the links, hence the
run, are off's. Prints, per setting, the robot-ticks, the messages delivered per robot-tick, the whole runs'
CPU per robot-tick and its change from off, and the CPU in the shadowing's own code (drawing the field once a
run, each tick's pair terms and the count of eq. 4's wrong calls, timed as above) and its ratio to the rest. A
run with the field unfolds otherwise than off (other links, so other messages heard and merged): its change
from off carries that difference too; ``code only``'s is the code's cost alone.
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
               (envelope, "expand"): probe.wrap(envelope.expand, when=lambda p: bool(p) and p[0] == 0x78),
               (Medium, "enqueue"): probe.wrap(Medium.enqueue, before=_encode_first),
               (Medium, "serve"): probe.wrap(Medium.serve)}
    for (owner, name), fn in wrapped.items():
        setattr(owner, name, fn)

def install_shadowing(probe: Probe, zeroed: list[bool]) -> None:
    """Wrap the shadowing's own code (this process only): the field's draw, the pair terms, the count; while
    ``zeroed[0]``, the pair terms are computed and then replaced by zeros."""
    from fleet_emu.core.shadowing import Shadowing
    from fleet_emu.netem import channel

    for owner, name in ((channel, "shadowing"), (channel, "count_predictions")):
        setattr(owner, name, probe.wrap(getattr(owner, name)))
    timed = probe.wrap(Shadowing.pair_db)

    def pair_db(self: Shadowing, cells: Any) -> Any:
        s = timed(self, cells)
        return s * 0.0 if zeroed[0] else s

    Shadowing.pair_db = pair_db  # type: ignore[method-assign]


def shadowing_table(a: Any) -> int:
    """``--shadowing``: the table of the module docstring's second command."""
    import fleet_emu as fe

    probe, zeroed = Probe(), [False]
    install_shadowing(probe, zeroed)
    pair = _probe_cost()
    fe.Fleet(fe.Scenario().override(max_ticks=20, shadowing_db=a.shadowing_db)).run()  # warm the kernels
    print(f"# {machine()}")
    print(f"# office, {a.robots} robots minpos, wall radio, loss 0.1, {a.seeds} seed(s) x {a.max_ticks} ticks at "
          f"most; shadowing {a.shadowing_db:g} dB, {a.shadowing_m:g} m; CPU of this process")
    print(f"{'shadowing':>9} {'robot-ticks':>11} {'delivered':>9} {'ms/robot-tick':>13} {'vs off':>7} {'calls':>7} "
          f"{'shadow s':>8} {'rest s':>8} {'share':>7}")
    settings = {"off": 0.0, "code only": a.shadowing_db, f"{a.shadowing_db:g} dB": a.shadowing_db}
    own, calls, total, robot_ticks, delivered = ({k: 0.0 for k in settings} for _ in range(5))
    for seed in range(a.seeds):  # the settings in turn within each seed: a drifting machine affects them alike
        for label, db in settings.items():
            print(f"{label} seed {seed}", file=sys.stderr)
            s = fe.Scenario().override(seed=seed, robots=a.robots, allocator="minpos", max_ticks=a.max_ticks,
                                       shadowing_db=db, shadowing_m=a.shadowing_m)
            probe.cpu, probe.calls, zeroed[0] = 0.0, 0, label == "code only"
            t = time.process_time()
            result = fe.Fleet(s).run()
            total[label] += time.process_time() - t
            robot_ticks[label] += result["ticks"] * a.robots
            delivered[label] += result["radio"]["delivered"]
            own[label] += probe.cpu - probe.calls * pair / 2
            calls[label] += probe.calls
    off = 1000 * total["off"] / robot_ticks["off"]
    for label in settings:
        rest = total[label] - own[label] - calls[label] * pair
        per = 1000 * total[label] / robot_ticks[label]
        print(f"{label:>9} {robot_ticks[label]:>11.0f} {delivered[label] / robot_ticks[label]:>9.2f} {per:>13.3f} "
              f"{per / off - 1:>+7.1%} {calls[label]:>7.0f} {own[label]:>8.3f} {rest:>8.3f} {own[label] / rest:>7.2%}")
    return 0


def main(argv: list[str] | None = None) -> int:
    p = parser("benchmarks.radio_cost", __doc__)
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--bandwidths", type=float, nargs="+", default=[1000.0, 64.0, 16.0])
    p.add_argument("--max-ticks", type=int, default=None, help="default 3000; 200 with --shadowing")
    p.add_argument("--shadowing", action="store_true", help="time the correlated shadowing instead")
    p.add_argument("--robots", type=int, default=16, help="--shadowing: the fleet's size")
    p.add_argument("--shadowing-db", type=float, default=8.0)
    p.add_argument("--shadowing-m", type=float, default=0.8)
    a = p.parse_args(argv)
    if a.seeds < 1 or any(b <= 0 for b in a.bandwidths):
        fail("radio_cost", "--seeds must be at least 1 and every bandwidth above 0")
    if a.max_ticks is not None and a.max_ticks < 1:
        fail("radio_cost", "--max-ticks must be at least 1")
    if a.shadowing:
        if not (1 <= a.robots <= 256 and 0 < a.shadowing_db <= 100 and a.shadowing_m > 0):
            fail("radio_cost", "--robots must be 1 to 256, --shadowing-db within (0, 100] and --shadowing-m above 0")
        a.max_ticks = a.max_ticks or 200
        return shadowing_table(a)
    a.max_ticks = a.max_ticks or 3000
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
