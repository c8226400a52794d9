"""What a run leaves behind: the recorder that writes ``run.mcap``, the launcher's monitor fold, the Foxglove
channels, and reading a recording back (metrics, tables, plots, ``fleet report``).

In a notebook::

    from fleet_emu.recording import load_recording
    run = load_recording("runs/<id>")        # or runs/<id>/run.mcap
    ticks, coverage = run.coverage_curve()
"""

from fleet_emu.recording.read import Run, load_recording

__all__ = ["Run", "load_recording"]
