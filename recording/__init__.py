"""What a run leaves behind: the recorder that writes ``run.mcap``, the launcher's monitor fold, the Foxglove
channels, and reading a recording back (metrics, tables, plots, ``fleet report``)."""
