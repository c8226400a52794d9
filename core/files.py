"""Files written whole: :func:`write_atomic` writes a temporary file beside the target and renames it over, and
removes the temporary file on any error, so that a reader, a crash or a full disk never leaves half a file or a
stray temporary one behind."""

from __future__ import annotations

import contextlib
import json
import os
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import Any


def write_atomic(path: Path, write: Callable[[Path], Any]) -> None:
    """``write(tmp)`` into a temporary file beside ``path``, then renamed over it; on any error the temporary
    file is removed and the error propagates (``path`` is then as it was)."""
    tmp = _new_temporary(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _new_temporary(path: Path) -> Path:
    """A new empty file ``.<stem>.tmp<random><suffix>`` beside ``path`` (the suffix kept: a writer may infer the
    format from it), with the mode any new file gets (the umask's)."""
    while True:
        tmp = path.with_name(f".{path.stem}.tmp{secrets.token_hex(4)}{path.suffix}")
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666))
            return tmp
        except FileExistsError:
            continue


def write_json(path: Path, obj: Any) -> None:
    """JSON (indented) to ``path``, atomically."""
    data = json.dumps(obj, indent=2)
    write_atomic(path, lambda tmp: tmp.write_text(data))
