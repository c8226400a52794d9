"""Versions that travel with data: the package's release and the bus message schema, stamped on envelopes,
``result.json`` and recordings. Here, at the bottom of the layering, so that ``core`` and ``recording`` read them
without importing the ``fleet_emu`` façade (which re-exports both); pyproject.toml reads ``__version__`` from this
file too."""

from __future__ import annotations

#: Bumped whenever a message, ``result.json`` or the recording layout changes incompatibly. 1: the first layout;
#: 2: fleet_emu namespace, opaque radio envelopes.
SCHEMA_VERSION = 2

#: The release of fleet_emu (``fleet_emu.__version__``; the package metadata's version).
__version__ = "0.2.0"
