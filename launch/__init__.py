"""The user's entry: the ``fleet`` CLI, the embedded router, spawning and supervising, recording, reports."""
