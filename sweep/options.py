"""``fleet sweep``'s numbers, each declared once (:func:`fleet_emu.core.fields.setting`, as a scenario's fields
are): its flag, metavar, range, default and help, and the one-line error of a value out of range, follow from
the declaration. None means not given: the default the help names."""

from __future__ import annotations

import dataclasses

from fleet_emu.core.fields import Setting, check_all, setting, settings


@dataclasses.dataclass(frozen=True)
class SweepOptions:
    """How much of a study to run and how its claims are judged."""

    jobs: int | None = setting(None, kind=int, low=1, high=4096, optional=True, unset="the number of cores",
                               metavar="N", help="parallel runs")
    limit: int | None = setting(None, kind=int, low=1, high=10**9, optional=True, unset="every run", metavar="N",
                                help="run only N more runs, spread over the grid: every allocator at settings far "
                                     "apart, each point's first seed before any second (a quick look; a later call "
                                     "continues)")
    seeds: int | None = setting(None, kind=int, low=1, high=10**6, optional=True, unset="all of them", metavar="N",
                                help="run only the study's first N seeds of every point (a quick look; a later "
                                     "call completes it)")
    max_seeds: int | None = setting(None, kind=int, low=1, high=10**6, optional=True,
                                    unset="4 x the study's seeds, or every value listed", metavar="N",
                                    help="with --until-decided: the most replicates (seeds, or the values of a "
                                         "study's [study] more key)")
    level: float = setting(0.95, low=0.5, high=0.999, metavar="L", help="the claims' confidence level")


def sweep_settings() -> tuple[Setting, ...]:
    """The declaration of every :class:`SweepOptions` field, in order (flags, checks)."""
    return settings(SweepOptions)


def check_sweep_options(**given: int | float | None) -> None:
    """A ConfigError of one line naming the first of ``given`` (field names, None: not given) out of its range."""
    check_all(SweepOptions(**{k: v for k, v in given.items() if v is not None}))  # type: ignore[arg-type]
