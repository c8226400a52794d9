"""The benchmark scripts as the tests call them: a script's ``main(argv)`` in this process, and its tables read by
their header names (a fixed-width row, a Markdown table)."""

from __future__ import annotations

import importlib
import re
from collections.abc import Sequence

import pytest


def bench(script: str, *argv: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """``benchmarks/SCRIPT.py``'s ``main(argv)``: (exit code, stdout, stderr)."""
    main = importlib.import_module(f"benchmarks.{script}").main
    capsys.readouterr()
    try:
        code = main(list(argv)) or 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    out, err = capsys.readouterr()
    return code, out, err


def fields(header: str, row: str, labels: Sequence[str | tuple[str, str]]) -> dict[str, str]:
    """A fixed-width table row as ``{label: text}``: each word of the row goes to the header label it lies under
    (right- or left-aligned, it overlaps the label's characters). ``labels`` in header order, each a label or
    ``(key, label)`` for a label the header repeats; words after the last label are the row's ``"rest"``."""
    spans, at = [], 0
    for item in labels:
        key, label = item if isinstance(item, tuple) else (item, item)
        start = header.index(label, at)
        assert header[start - 1:start] in ("", " ") and header[start + len(label):][:1] in ("", " "), label
        spans.append((key, start, start + len(label)))
        at = start + len(label)
    out: dict[str, list[str]] = {}
    for word in re.finditer(r"\S+", row):
        keys = [k for k, s, e in spans if word.start() < e and s < word.end()]
        if not keys:
            assert word.start() >= at, f"{word.group()!r} at {word.start()} is under no label of {header!r}"
            keys = ["rest"]
        assert len(keys) == 1, (word.group(), keys)
        out.setdefault(keys[0], []).append(word.group())
    return {k: " ".join(v) for k, v in out.items()}


def markdown(text: str) -> list[dict[str, str]]:
    """The rows of the Markdown table in ``text`` as ``{header: cell}``."""
    lines = [ln for ln in text.splitlines() if ln.startswith("|") and not ln.startswith("| ---")]
    head = [c.strip() for c in lines[0].strip("|").split("|")]
    return [dict(zip(head, (c.strip() for c in ln.strip("|").split("|")), strict=True)) for ln in lines[1:]]
