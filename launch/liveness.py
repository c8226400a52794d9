"""One run per run id on a router: a run whose ``--run-id`` is already live there is refused before it starts.

A live run holds its launcher's liveliness token (``fleet/<run>/alive/launcher/launcher``) from the moment its
sessions open to its end. A second run with the same id on the same router would share every key with the
first: its nonce keeps the two runs from taking each other's messages, but the first run's nodes would drop
the second's traffic all along, and both would compete for one recording's keys. So ``fleet run --connect``
asks the router for that token first, and refuses with one line when another run holds it.
"""

from __future__ import annotations

import zenoh

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.keys import Keys

QUERY_TIMEOUT = 2.0  # seconds the router's answer may take (it answers at once when no token matches)


def run_is_live(session: zenoh.Session, run_id: str) -> bool:
    """Whether a launcher of run ``run_id`` holds its liveliness token on the router of ``session``."""
    replies = session.liveliness().get(Keys(run_id).alive("launcher", "launcher"), timeout=QUERY_TIMEOUT)
    return any(reply.ok is not None for reply in replies)


def check_run_id_free(session: zenoh.Session, run_id: str, endpoint: str) -> None:
    """A ConfigError (one line, exit 2) when run ``run_id`` is already live on the router at ``endpoint``
    (an empty ``run_id``: the launcher makes a fresh one, nothing to check)."""
    if run_id and run_is_live(session, run_id):
        raise ConfigError(f"run id {run_id!r} is already live on {endpoint} (another run holds its launcher's "
                          f"liveliness token): choose another --run-id, or wait for that run to end")
