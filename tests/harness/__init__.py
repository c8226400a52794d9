"""The tests' shared helpers, imported by test modules (which import neither a ``conftest`` nor one another:
``tests/test_layering.py`` checks it) and by the benchmark scripts: ``cli`` (the ``fleet`` CLI as a user runs it
and in this process, a run's ``result.json``), ``procs`` (a run's processes from outside), ``files`` (drawn maps,
certificates, a tmpfs, a crafted MCAP), ``lockstep`` (a drawn fleet on the memory engine), ``map_mirror`` (the
public maps as a ``--mirror`` folder), ``docs`` (the pages' fenced blocks), ``bench`` (a benchmark script's
``main`` and its tables), ``faults`` and ``fuzz`` (the fault trials), and one subject's material each
(``wire``, ``spy``, ``mhm``, ``stall``, ``foxglove``, ``sweep``, ``stalled_viewer``)."""
