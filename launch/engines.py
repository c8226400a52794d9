"""One path from a run's options to a run, for ``fleet run`` and ``fe.run`` alike: the engine named, the
options it cannot take refused (one list, each option named as the user wrote it: the flag from the CLI, the
keyword from Python, :func:`fleet_emu.core.setting_names.option`), then the memory engine
(``launch/memory.py``) or the processes engine (``launch/runner.py``) started with the same
:class:`~fleet_emu.launch.runner.RunOptions`. Nothing heavy is imported until a run starts."""

from __future__ import annotations

from typing import TYPE_CHECKING

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.setting_names import option

if TYPE_CHECKING:
    from fleet_emu.core.scenario import Scenario
    from fleet_emu.launch.runner import RunOptions
    from fleet_emu.recording.result import Result

#: The engines: one OS process per node over Zenoh, or the same objects stepped in this process.
ENGINES = ("processes", "memory")
#: The options only the processes engine takes: a :class:`RunOptions` field and its flag when that is not the
#: field's name (``--[no-]fork-server``); a value other than the field's default is one the user gave.
BUS_OPTIONS = (("in_process", ""), ("connect", ""), ("credentials", ""), ("tls_ca", ""), ("listen", ""),
               ("tls_cert", ""), ("tls_key", ""), ("host_timeout", ""), ("fork_server", "--[no-]fork-server"),
               ("companions", "ros2"))


def check_engine(scenario: Scenario, engine: str, opts: RunOptions) -> None:
    """A ConfigError of one line when ``engine`` is not one of :data:`ENGINES`, or is the memory engine (lockstep
    in this process) and ``opts`` or the scenario's ``[hosts]`` ask for a bus, processes or real time, or when the
    Foxglove grids' rate is not a whole number of ticks."""
    from fleet_emu.launch.runner import RunOptions

    if opts.grid_every is not None and (isinstance(opts.grid_every, bool) or not isinstance(opts.grid_every, int)
                                        or opts.grid_every < 1):
        raise ConfigError(f"{option('grid_every')} must be a whole number of ticks, at least 1 "
                          f"(got {opts.grid_every!r})")
    if engine not in ENGINES:
        raise ConfigError(f"{option('engine')} must be one of {', '.join(ENGINES)} (got {engine!r})")
    if engine != "memory":
        return
    name = option("engine", flag="--engine memory")  # the flag from the CLI; from Python, as the docs say it
    name = name if name.startswith("--") else "the memory engine"
    if opts.realtime_hz is not None:
        raise ConfigError(f"{option('realtime_hz', flag='--realtime')} needs the processes engine: {name} is "
                          f"lockstep only")
    default = RunOptions()
    for field, flag in BUS_OPTIONS:
        if getattr(opts, field) != getattr(default, field):
            spelt = option(flag) if flag and not flag.startswith("--") else option(field, flag=flag)
            raise ConfigError(f"{name} runs without Zenoh nor processes: it takes no {spelt}")
    if scenario.hosts is not None:
        raise ConfigError(f"{name} runs without Zenoh nor processes: it takes no [hosts] (the scenario's; "
                          f"{option('hosts', '0', flag='--hosts 0')} runs every robot here)")


def start_run(scenario: Scenario, engine: str, opts: RunOptions) -> Result:
    """Run ``scenario`` on ``engine`` with ``opts`` (checked first, :func:`check_engine`) and return its result:
    what ``fleet run`` and ``fe.run`` both call."""
    from fleet_emu.launch.checks import check_options

    check_engine(scenario, engine, opts)
    if engine == "memory":
        from fleet_emu.launch.memory import run_memory
        from fleet_emu.launch.runner import RunOptions

        check_options(RunOptions(run_id=opts.run_id))  # as the processes engine: a bad run id is one line
        return run_memory(scenario, opts.out_dir, record=opts.record, run_id=opts.run_id, grid_every=opts.grid_every,
                          on_progress=opts.on_progress, interrupts=opts.interrupts, overwrite=opts.overwrite,
                          live=opts.live)
    from fleet_emu.launch.runner import run_fleet

    return run_fleet(scenario, opts)
