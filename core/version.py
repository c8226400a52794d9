"""Versions that travel with data: the bus message schema, stamped on envelopes, result.json and recordings."""

from __future__ import annotations

#: Bumped whenever a message, ``result.json`` or the recording layout changes incompatibly. 1: the first layout;
#: 2: fleet_emu namespace, opaque radio envelopes.
SCHEMA_VERSION = 2
