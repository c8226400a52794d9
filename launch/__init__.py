"""The user's entry: the ``fleet`` CLI, scenarios, the embedded router, spawning and supervising, progress.

Recording and reports are :mod:`fleet_emu.recording`.
"""
