"""``fleet``'s commands that run and inspect fleets: ``run``, ``router-config``, ``host``, ``maps``,
``allocators``, ``report``, ``recover``, and the dispatch every command goes through (docs/reference/cli.md). The
``fleet`` console script, :mod:`fleet_emu.cli`, adds ``sweep`` on top (sweep runs fleets through this package,
so this package does not import it); ``python -m fleet_emu.launch`` serves the commands here.

Bad input gets one line on stderr (``fleet: error: ...``) and exit code 2; a run in which a process of the
fleet failed exits 1 (a robot too, when the others finished, unless the scenario crashed it); SIGINT (Ctrl-C)
exits 130 and SIGTERM 143, after writing ``result.json`` and closing the recording (``launch/signals.py``).
This module imports nothing heavy at the top, so that a signal during start-up meets the handler, not a
half-imported module.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from fleet_emu.core.errors import ConfigError, FleetError
from fleet_emu.core.setting_names import cli_spelling
from fleet_emu.core.version import __version__
from fleet_emu.launch.maps_cli import add_parser as add_maps
from fleet_emu.launch.maps_cli import cmd_maps

if TYPE_CHECKING:
    from fleet_emu.core.scenario import Scenario
    from fleet_emu.launch.signals import Interrupts

DEFAULT_SCENARIO = Path(__file__).resolve().parent / "scenarios" / "default.toml"
#: What a bare ``fleet`` prints after its help.
START_HINT = ("`fleet run` starts the default fleet (4 robots exploring the built-in office); "
              "`fleet COMMAND --help` describes a command.")


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, exit 2 (argparse's default prints usage too)
        _fail(message + _did_you_mean(self, message))


def _did_you_mean(parser: argparse.ArgumentParser, message: str) -> str:
    """``; did you mean '--robots'?`` for argparse's "unrecognized arguments" (a flag close to one of any
    command's) or "invalid choice" (a command, an engine...) when a known name is close, else ""."""
    import re

    from fleet_emu.core.setting_names import near

    choice = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
    if choice:
        return near(choice.group(1), re.findall(r"'([^']*)'", choice.group(2)))
    if message.startswith("unrecognized arguments:"):
        flags = [f for f in message.split(":", 1)[1].split() if f.startswith("--")]
        return next((hint for hint in (near(f.split("=")[0], _flags(parser)) for f in flags) if hint), "")
    return ""


def _flags(parser: argparse.ArgumentParser) -> list[str]:
    """Every long flag of ``parser`` and of its commands."""
    out: list[str] = []
    for action in parser._actions:
        out += [s for s in action.option_strings if s.startswith("--")]
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                out += _flags(sub)
    return sorted(set(out))


def _fail(message: str, code: int = 2) -> NoReturn:
    print(f"fleet: error: {message}", file=sys.stderr)
    raise SystemExit(code)


def _hz(text: str) -> float:
    try:
        hz = float(text)
    except ValueError:
        hz = float("nan")
    if not 0 < hz <= 1000:  # NaN fails too
        raise argparse.ArgumentTypeError(f"expected ticks per second, a number > 0 and <= 1000, got {text!r}")
    return hz


#: A subcommand's handler: its parsed arguments to the exit code.
Handler = Callable[[argparse.Namespace], int]
#: Adds a subcommand (or several) to the ``fleet`` parser's subparsers.
Adder = Callable[[Any], None]


def build_parser(extra: Sequence[Adder] = ()) -> argparse.ArgumentParser:
    """The ``fleet`` parser with this package's commands (``run``, ``router-config``, ``host``, ``maps``,
    ``allocators``, ``report``) and those ``extra`` adds (``fleet_emu.cli`` adds ``sweep``)."""
    p = _Parser(prog="fleet", description="Multi-robot exploration under realistic radio, over Eclipse Zenoh.")
    p.add_argument("--version", action="version", version=f"fleet-emu {__version__}")
    sub = p.add_subparsers(dest="command", parser_class=_Parser)
    for add in (_add_run, _add_router_config, _add_host, _add_listings, _add_report, *extra):
        add(sub)
    return p


def _add_run(sub: Any) -> None:
    r = sub.add_parser("run", help="run one scenario (the default one with no arguments)")
    _add_scenario_flags(r)
    _add_engine_flags(r)
    _add_bus_flags(r)
    r.add_argument("--quiet", action="store_true",
                   help="no progress bar and no summary table: print only the path of result.json (for scripts)")
    r.add_argument("--grid-every", type=int, metavar="K",
                   help="Foxglove map/coverage/belief grids in run.mcap every K ticks, K from 1 "
                        "(default: the scenario's belief_every)")
    r.add_argument("--live", metavar="[HOST:]PORT",
                   help="serve the run to Foxglove over WebSocket (host 127.0.0.1 unless given; port 0: one the OS "
                        "picks); prints `live: ws://HOST:PORT` on stderr once up")
    r.add_argument("--live-hz", type=_hz, metavar="HZ",
                   help="with --live: at most HZ lockstep ticks per second, to watch a fast run (same result; default: "
                        "as fast as it goes)")


def _add_scenario_flags(r: argparse.ArgumentParser) -> None:
    """``fleet run``'s scenario and its overrides: a flag per declared scenario and radio setting
    (``launch/setting_flags.py``), and by hand those of the fields that hold a table or a choice of forms: the
    allocator and its parameters, the base station, the faults (``--hosts`` is with the bus's flags)."""
    # here, not at the top: the dispatcher's signal handler is in place
    from fleet_emu.core.fields import cell_arg
    from fleet_emu.core.scenario import scenario_settings
    from fleet_emu.launch.radio_flags import add_radio_flags
    from fleet_emu.launch.setting_flags import add_setting_flags

    r.add_argument("scenario_file", nargs="?", type=Path, metavar="SCENARIO",
                   help="a scenario TOML or a run's scenario.json, as --scenario")
    r.add_argument("--scenario", type=Path, help="a scenario TOML, a run's scenario.json, or a shipped scenario's name "
                                                 "(`default` or `connectivity`; default: the one named `default`)")
    group = r.add_argument_group("scenario", "the scenario's settings, one flag per field (docs/reference/scenario.md)")
    add_setting_flags(group, scenario_settings())
    group.add_argument("--allocator", help="allocator name (see `fleet allocators`) (default minpos, or the "
                                           "scenario's)")
    group.add_argument("--param", action="append", metavar="NAME=VALUE",
                       help="an allocator parameter (repeatable; see `fleet allocators` for each one's range and "
                            "default), e.g. --param path=policy.npz")
    group.add_argument("--base", action="store_const", const=True, default=None,
                       help="a base station (its own process) at the start cell; see --base-cell (default: none, or "
                            "the scenario's)")
    group.add_argument("--base-cell", type=cell_arg, metavar="ROW,COL",
                       help="a base station at this cell (default: none, or the scenario's)")
    group.add_argument("--crash", action="append", metavar="ROBOT@TICK",
                       help="robot ROBOT (r1, or 1) crashes at tick TICK: it leaves the run and its body stays where "
                            "it stood (repeatable; replaces the scenario's [[faults]]; docs/guides/faults.md; "
                            "default: none, or the scenario's)")
    add_radio_flags(r)


def _add_engine_flags(r: argparse.ArgumentParser) -> None:
    """``fleet run``'s output, engine and process options."""
    from fleet_emu.launch.engines import ENGINES

    r.add_argument("--out", type=Path, help="output directory (default runs/<run id>); one that holds a run is "
                                            "refused unless --overwrite, one another run is writing always")
    r.add_argument("--overwrite", action="store_true",
                   help="--out holds a run: remove its files (result, recording, logs, plots) before starting")
    r.add_argument("--engine", choices=ENGINES, default="processes",
                   help="processes: one OS process per node over Zenoh; memory: the same objects stepped in this "
                        "process, no Zenoh (same result for a seed; default: processes)")
    r.add_argument("--in-process", action="store_true", help="all nodes in this process (one session each)")
    r.add_argument("--realtime", type=_hz, metavar="HZ",
                   help="real time: the world ticks HZ times a second on the wall clock, whether or not every robot "
                        "has answered (not deterministic; default: lockstep)")
    r.add_argument("--fork-server", action=argparse.BooleanOptionalAction, default=None,
                   help="fork the robot, world, netem and base processes from one fork server that loaded the code "
                        "once (default: on, unless FLEET_FORK_SERVER=0); --no-fork-server starts each afresh")
    r.add_argument("--no-record", action="store_true", help="do not write run.mcap")
    r.add_argument("--run-id", help="the <run> of the key expressions (default: a timestamp)")


def _add_bus_flags(r: argparse.ArgumentParser) -> None:
    """``fleet run``'s bus: an external router and its logins, the embedded router's endpoint, the hosts."""
    r.add_argument("--connect", help="use an external Zenoh router, e.g. tcp/192.0.2.1:7447")
    r.add_argument("--credentials", type=Path, metavar="USERS",
                   help="with --connect: the users file written by `fleet router-config`")
    r.add_argument("--tls-ca", type=Path, metavar="CA.pem", help="with a tls/ --connect: the CA that signed the router")
    r.add_argument("--hosts", type=int, metavar="N",
                   help="deal the robots round-robin between this machine and N `fleet host`s, waiting for them, "
                        "N from 0 to 64 (replaces the scenario's [hosts]; 0: every robot here; default: the "
                        "scenario's [hosts], none in the default one)")
    r.add_argument("--listen", metavar="ENDPOINT",
                   help="the embedded router's endpoint, one the hosts reach (e.g. tcp/192.0.2.1:7447)")
    r.add_argument("--tls-cert", type=Path, metavar="CERT.pem",
                   help="with a tls/ or quic/ --listen: the embedded router's certificate (signed by a CA)")
    r.add_argument("--tls-key", type=Path, metavar="KEY.pem", help="with --tls-cert: its private key")
    r.add_argument("--host-timeout", type=float, default=None, metavar="S",
                   help="seconds to wait for the --hosts, > 0 (default 60)")


def _add_router_config(sub: Any) -> None:
    rc = sub.add_parser("router-config", help="print a zenohd configuration with the fleet's authentication and "
                                              "access control, and write its users file")
    rc.add_argument("--robots", type=int, required=True, help="robots r0..r<N-1> that may join")
    rc.add_argument("--users", type=Path, required=True,
                    help="the users file (user:password lines, mode 0600); kept passwords are reused")
    rc.add_argument("--listen", default=None, help="endpoint (default tcp/0.0.0.0:7447, or tls/0.0.0.0:7447 "
                                                   "with --tls-cert)")
    rc.add_argument("--run-id", action="append", default=None,
                    help="the one run this router serves (default: any); given more than once, each run id with "
                         "logins of its own, written to USERS-ID beside --users")
    rc.add_argument("--hosts", type=int, default=0, help="hosts host0..host<N-1> that may join (`fleet host`)")
    rc.add_argument("--tls-cert", type=Path, help="the router's TLS certificate (PEM)")
    rc.add_argument("--tls-key", type=Path, help="its private key (PEM)")


def _add_host(sub: Any) -> None:
    h = sub.add_parser("host", help="start the robots a `fleet run --hosts N` on another machine assigns here")
    h.add_argument("--connect", required=True, help="the run's Zenoh router, e.g. tcp/192.0.2.1:7447")
    h.add_argument("--credentials", type=Path, metavar="FILE",
                   help="this host's login: a hostK:password line (of `fleet router-config --hosts N`'s users file)")
    h.add_argument("--connect-timeout", type=float, default=5.0, metavar="S",
                   help="seconds to keep trying the router (started before `fleet run`: give it time; default 5)")
    h.add_argument("--name", help="the host's user in --credentials when it holds several (default: its one host)")
    h.add_argument("--tls-ca", type=Path, metavar="CA.pem", help="with a tls/ --connect: the CA that signed the router")
    h.add_argument("--out", type=Path, help="where the robots' logs go (default runs/<run id>/<host>)")
    h.add_argument("--once", action="store_true", help="exit after one run (default: serve runs until Ctrl-C)")
    h.add_argument("--fork-server", action=argparse.BooleanOptionalAction, default=None,
                   help="fork the robots from a fork server (default: as the launcher asks)")


def _add_listings(sub: Any) -> None:
    add_maps(sub)
    sub.add_parser("allocators", help="list the allocators (built-in and installed plugins) and their parameters")
    from fleet_emu.launch.radio_cli import add_parser as add_radio

    add_radio(sub)


def _add_report(sub: Any) -> None:
    rep = sub.add_parser("report", help="metrics.json, plots and a table from a recording (RUN_DIR or RUN.mcap)")
    rep.add_argument("paths", nargs="*", type=Path, metavar="RUN", help="a run directory or its run.mcap")
    rep.add_argument("--compare", action="store_true", help="one table and overlaid coverage curves of the runs")
    rep.add_argument("--out", type=Path, help="where --compare writes its PNG (default ./compare.png)")
    rep.add_argument("--no-plots", action="store_true", help="metrics.json and the table only")
    rep.add_argument("--partial", action="store_true",
                     help="report what a cut or inconsistent recording holds (without it: refused, saying how much "
                          "reads; a run whose launcher died, with no result.json, is recovered first either way)")
    rep.add_argument("--layout", type=Path, metavar="FILE",
                     help="write the Foxglove layout for a recording or a live run (--live) to FILE (JSON)")
    rep.add_argument("--robots", type=int, metavar="N",
                     help="with --layout: the robots it plots, from 1 to 1024 (default: the run's robots; 8 without "
                          "a run, for a live one)")
    rep.add_argument("--base", action="store_true",
                     help="with --layout: plot the base-connected fraction (default: when a run has a base station; "
                          "for a live run with one, give it)")
    from fleet_emu.launch.recover import add_parser as add_recover

    add_recover(sub)
    info = sub.add_parser("info", help="a recording's summary: its run and scenario, messages, duration and "
                                       "channels (as `mcap info`)")
    info.add_argument("path", type=Path, metavar="RUN", help="a run directory or its run.mcap")


def scenario_from_args(args: argparse.Namespace) -> Scenario:
    """The scenario ``fleet run`` was given (a file, else the default one) with its flags on top."""
    from fleet_emu.core.scenario import Scenario, scenario_settings
    from fleet_emu.launch.radio_flags import radio_overrides
    from fleet_emu.launch.setting_flags import given

    path = getattr(args, "scenario_file", None)
    if path is not None and args.scenario is not None:
        raise ConfigError(f"two scenarios given ({path} and --scenario {args.scenario}): give one")
    base = Scenario.load(path or args.scenario or DEFAULT_SCENARIO)
    return base.override(
        **given(args, scenario_settings()), **radio_overrides(args),
        allocator=_allocator_arg(base, getattr(args, "allocator", None), getattr(args, "param", None)),
        base=args.base_cell if getattr(args, "base_cell", None) is not None else getattr(args, "base", None),
        hosts=getattr(args, "hosts", None), faults=_crash_args(getattr(args, "crash", None)))


def _crash_args(given: list[str] | None) -> list[dict[str, Any]] | None:
    """``--crash ROBOT@TICK`` (repeatable) as ``[[faults]]`` entries; None when not given. ConfigError on one not
    of that form (the entries' values are checked with the scenario's)."""
    if not given:
        return None
    out = []
    for item in given:
        robot, at, tick = item.partition("@")
        if not at or not robot or not tick.strip().isdigit():
            raise ConfigError(f"--crash must be ROBOT@TICK, e.g. r1@30 (got {item!r})")
        out.append({"robot": int(robot) if robot.isdigit() else robot, "tick": int(tick), "kind": "crash"})
    return out


def _allocator_arg(base: Scenario, name: str | None, params: list[str] | None) -> str | dict[str, Any] | None:
    """``--allocator`` with its ``--param NAME=VALUE`` (a number, true/false, or else a string), over the
    scenario's table when it names the same allocator; ConfigError on a parameter not of that form."""
    if not params:
        return name
    kind = name or base.allocator.get("type")
    table = dict(base.allocator) if kind == base.allocator.get("type") else {"type": kind}
    for item in params:
        key, eq, text = item.partition("=")
        if not eq or not key:
            raise ConfigError(f"--param must be NAME=VALUE (got {item!r})")
        table[key] = param_value(text)
    return table


def param_value(text: str) -> bool | int | float | str:
    """A ``NAME=VALUE`` item's value: true/false, an integer, a number, else the string."""
    if text in ("true", "false"):
        return text == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def cmd_run(args: argparse.Namespace, interrupts: Interrupts) -> int:
    import dataclasses

    from rich.console import Console

    from fleet_emu.launch.checks import new_run_id
    from fleet_emu.launch.engines import check_engine, start_run
    from fleet_emu.launch.live import live_options
    from fleet_emu.launch.progress import Progress
    from fleet_emu.launch.runner import RunOptions

    console = Console(stderr=True)
    scenario = scenario_from_args(args)
    run_id = args.run_id or new_run_id()
    out = args.out or Path("runs") / run_id
    live = live_options(args.live, args.live_hz, args.realtime is not None)
    # a layer above this package (the ROS 2 bridge) may add clients of the bus: fleet_emu/cli.py sets this
    companions = args.companions(args) if getattr(args, "companions", None) is not None else None
    opts = RunOptions(out_dir=out, in_process=args.in_process, record=not args.no_record, connect=args.connect,
                      run_id=run_id, grid_every=args.grid_every, credentials=args.credentials, tls_ca=args.tls_ca,
                      interrupts=interrupts, on_warning=_warn, fork_server=args.fork_server,
                      on_note=None if args.quiet else _note, listen=args.listen, realtime_hz=args.realtime,
                      tls_cert=args.tls_cert, tls_key=args.tls_key, overwrite=args.overwrite, live=live,
                      **(companions.options if companions is not None else {}),
                      **({"host_timeout": args.host_timeout} if args.host_timeout is not None else {}))
    check_engine(scenario, args.engine, opts)  # before the progress bar shows
    with Progress(scenario, run_id, console, quiet=args.quiet) as progress:
        result = start_run(scenario, args.engine, dataclasses.replace(opts, on_progress=progress.update))
    if interrupts.signum is not None:
        when = "" if result["reason"] == "interrupted" else f" after the run ended ({result['reason']})"
        print(f"fleet: interrupted by {interrupts.name}{when}; result.json and the recording are in {out}",
              file=sys.stderr)
        return interrupts.exit_code
    if not args.quiet:
        from fleet_emu.recording.tables import summary_table

        console.print(summary_table(result, str(out)))
    else:
        print(out / "result.json")
    return exit_code(result, out)


def _warn(message: str) -> None:
    print(f"fleet: warning: {message}", file=sys.stderr)


def _note(message: str) -> None:
    """What the run waits for (its hosts), on the console; nothing with ``--quiet``."""
    print(f"fleet: {message}", file=sys.stderr, flush=True)


def cmd_router_config(args: argparse.Namespace) -> int:
    from fleet_emu.launch.router_config import router_config_text

    print(router_config_text(args.robots, args.users, args.listen, args.run_id or "*", args.tls_cert, args.tls_key,
                             args.hosts))
    return 0


def exit_code(result: Mapping[str, Any], out: Path) -> int:
    """1 when a robot of the fleet failed (its process died or went silent), even if the rest of the fleet
    reached the target: a result that lost a robot is not the scenario that was asked for (a robot the scenario
    crashed, ``[[faults]]``, is what was asked for); 0 when the target coverage was reached; 3 when the run
    ended without it (tick limit, stall), with a line naming a failed robot whose body held the others off."""
    from fleet_emu.recording.result import unexpected_failures

    failed = unexpected_failures(result)
    if failed:
        print(f"fleet: error: robot(s) {', '.join(failed)} of {result['robots']} failed and left the run (reason "
              f"{result['reason']}); see their logs in {out}", file=sys.stderr)
        return 1
    for robot, block in result.get("blocked_by", {}).items():
        print(f"fleet: {robot}'s body at cell {tuple(block['cell'])} cut the other robots off from "
              f"{block['cut_off']} cell(s) still to sense (reason {result['reason']})", file=sys.stderr)
    return 0 if result["completed"] else 3


def cmd_allocators(_: argparse.Namespace) -> int:
    from fleet_emu.agents.allocators import allocator_class, allocator_names

    for name in allocator_names():
        try:
            cls = allocator_class(name)
        except ConfigError as exc:  # a broken plugin is listed with its error; the others still work
            print(f"{name:14s} {exc}")
            continue
        params = [(f"{p}=<scenario {cls.scenario_fields[p]}>" if p in cls.scenario_fields else f"{p}={spec.default!r}")
                  + f" ({spec.span()})" for p, spec in cls.parameters.items()]
        source = "built-in" if cls.__module__.startswith("fleet_emu.") else f"plugin {cls.__module__}"
        print(f"{name:14s} {cls.summary() or '(no description)'} [{source}: {', '.join(params) or 'no parameters'}]")
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from fleet_emu.launch.recover import reporting
    from fleet_emu.recording.report import report

    if args.layout is not None:
        from fleet_emu.recording.layout import write_layout
        from fleet_emu.recording.read import recorded_scenario

        robots = args.robots  # given: it wins; else the runs' own (the largest fleet of them), else the default
        scenarios = [recorded_scenario(p) for p in args.paths]
        if robots is None and scenarios:
            robots = max(int(s["robots"]) for s in scenarios)
        base = args.base or any(s.get("base") not in (None, False) for s in scenarios)  # else its plot is null
        write_layout(args.layout, robots, base)
        print(args.layout)
    elif args.robots is not None or args.base:
        raise ConfigError(f"{'--robots' if args.robots is not None else '--base'} goes with --layout")
    if not args.paths and args.layout is None:
        raise ConfigError("give a run (RUN_DIR or RUN.mcap) to report on, or --layout FILE")
    if args.paths:
        with reporting(args.paths, args.partial) as recovered:  # run folders locked; a crashed run recovered first
            for line in recovered:
                print(line)
            report(args.paths, compare=args.compare, out=args.out, plots=not args.no_plots, partial=args.partial)
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    from fleet_emu.recording.info import info_lines, recording_info

    for line in info_lines(recording_info(args.path)):
        print(line)
    return 0


def cmd_recover(args: argparse.Namespace) -> int:
    from fleet_emu.launch.recover import cmd_recover as recover

    return recover(args)


def cmd_radio(args: argparse.Namespace) -> int:
    from fleet_emu.launch.radio_cli import cmd_radio as radio

    return radio(args)


#: The handlers of this package's commands other than ``run`` and ``host`` (which handle signals themselves).
HANDLERS: dict[str, Handler] = {"maps": cmd_maps, "allocators": cmd_allocators, "report": cmd_report,
                                "radio": cmd_radio,
                                "router-config": cmd_router_config, "recover": cmd_recover, "info": cmd_info}


def main(argv: list[str] | None = None) -> None:
    """``python -m fleet_emu.launch``: this package's commands, every one but ``sweep`` (the ``fleet`` console
    script, :func:`fleet_emu.cli.main`, has them all)."""
    serve(argv, build_parser, HANDLERS)


def serve(argv: list[str] | None, parser: Callable[[], argparse.ArgumentParser],
          handlers: Mapping[str, Handler]) -> NoReturn:
    """Parse ``argv`` with ``parser()`` (no command: the help, and how to start a fleet), run the command and
    exit with its code: ``run`` and ``host`` with SIGINT and SIGTERM turned into requests, the others
    (``handlers``) with Ctrl-C simply stopping them; an error meant for the user is one line."""
    from fleet_emu.launch.signals import Interrupts

    interrupts = Interrupts().install()  # first: a signal while parsing or importing is a request too
    command = "run"
    with cli_spelling():  # errors name flags, not Python keywords
        try:
            args = parser().parse_args(argv)
            command = args.command or "help"
            if command == "help":
                interrupts.restore()
                parser().print_help()
                print(f"\n{START_HINT}")
                code = 0
            elif command == "run":
                code = _run_with_signals(args, interrupts)
            elif command == "host":
                from fleet_emu.launch.host_server import cmd_host

                code = cmd_host(args, interrupts)
            else:
                interrupts.restore()  # a listing or a report: Ctrl-C simply stops it
                _ctrl_c_stops()
                if interrupts.requested.is_set():
                    raise KeyboardInterrupt
                code = handlers[command](args)
        except FleetError as exc:  # every error meant for the user, caught once: one line, its exit code
            interrupts.restore()
            _fail(str(exc), code=exc.exit_code)
        except KeyboardInterrupt:
            print("fleet: interrupted", file=sys.stderr)
            code = 130
        except BrokenPipeError:  # a listing piped into `head`: the reader left, nothing is wrong
            _quiet_stdout()
            code = 0
        finally:
            if command != "run":
                interrupts.restore()
    if command == "run":
        _ignore_signals_while_exiting()
    raise SystemExit(code)


def _ctrl_c_stops() -> None:
    """SIGINT raises KeyboardInterrupt even where the shell started this command with SIGINT ignored (a
    background job, a CI runner): ``kill -INT`` stops an export or a fetch as it stops ``fleet run``."""
    import signal

    if signal.getsignal(signal.SIGINT) in (signal.SIG_IGN, signal.SIG_DFL):
        signal.signal(signal.SIGINT, signal.default_int_handler)


def _quiet_stdout() -> None:
    """Point stdout at /dev/null, so that the interpreter's final flush into a closed pipe raises nothing
    (the recipe of Python's ``signal`` documentation)."""
    import os

    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def _ignore_signals_while_exiting() -> None:
    """The run's files are written: a SIGINT or SIGTERM from here on changes nothing, so it is ignored. (The
    handler would not do: the interpreter's finalization puts back the default action, and a signal then
    would kill the process with -2/-15 instead of the run's exit code; an ignored signal stays ignored.)"""
    import signal

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)


def _run_with_signals(args: argparse.Namespace, interrupts: Interrupts) -> int:
    """``fleet run`` with SIGINT and SIGTERM turned into requests (``launch/signals.py``), from before the
    run's heavy imports until it has written its files; a signal before the run could start still exits
    130/143 after writing an interrupted ``result.json``."""
    try:
        return cmd_run(args, interrupts)
    except FleetError as exc:
        if interrupts.signum is None:
            raise
        from fleet_emu.launch.outdir import DiskFault

        if isinstance(exc, DiskFault):  # a signal during a disk fault's teardown changes the code, not the line
            print(f"fleet: error: {exc}", file=sys.stderr)
        return interrupts.exit_code  # bad input found after the user already asked to stop: still a stop


if __name__ == "__main__":
    main()
