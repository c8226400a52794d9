"""fleet_emu: multi-robot frontier exploration under realistic radio, one process per robot over Eclipse Zenoh."""

__version__ = "0.2.0"
