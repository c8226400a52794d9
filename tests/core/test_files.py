"""``core/files.py``: a file created new never follows a link planted where it goes (a file left there is
unlinked, never truncated, so a hard link's other name keeps its content), a file written whole replaces a link
at its path instead of writing through it, and a user's file is read only when it is a regular file within its
size limit: a FIFO or a device is refused at once, never waited on."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from fleet_emu.core.files import NotRegularFile, TooLarge, create_new, open_new, read_regular, write_atomic


def test_create_new_refuses_a_link_and_unlinks_a_file_left_there(tmp_path: Path) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    (tmp_path / "r0.log").symlink_to(victim)
    with pytest.raises(NotRegularFile, match="symbolic link"):
        create_new(tmp_path / "r0.log")
    (tmp_path / "dangling.log").symlink_to(tmp_path / "new-target")  # O_CREAT would create the target
    with pytest.raises(NotRegularFile):
        create_new(tmp_path / "dangling.log")
    os.link(victim, tmp_path / "world.log")  # a hard link: the log is a new file, the victim keeps its bytes
    with open_new(tmp_path / "world.log") as f:
        f.write(b"log")
    assert victim.read_text() == "precious" and not (tmp_path / "new-target").exists()
    assert (tmp_path / "world.log").read_bytes() == b"log"


def test_write_atomic_replaces_a_link_at_its_path_and_leaves_no_temporary(tmp_path: Path) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    (tmp_path / "result.json").symlink_to(victim)
    write_atomic(tmp_path / "result.json", lambda tmp: tmp.write_text("{}"))
    assert victim.read_text() == "precious"
    assert not (tmp_path / "result.json").is_symlink() and (tmp_path / "result.json").read_text() == "{}"
    write_atomic(tmp_path / "users.txt", lambda tmp: tmp.write_text("r0:secret"), mode=0o600)
    assert (tmp_path / "users.txt").stat().st_mode & 0o777 == 0o600
    (tmp_path / "users.txt").unlink()
    with pytest.raises(RuntimeError):
        write_atomic(tmp_path / "x.json", _half_then_fail)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.json", "victim.txt"]


def _half_then_fail(tmp: Path) -> None:
    tmp.write_text("half")
    raise RuntimeError("a writer that fails")


def test_read_regular_refuses_a_fifo_a_device_a_folder_and_an_oversize_file(tmp_path: Path) -> None:
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)  # no writer: a blocking open would wait for ever
    for path, kind in ((fifo, "FIFO"), (Path("/dev/zero"), "device"), (tmp_path, "folder")):
        with pytest.raises(NotRegularFile, match=kind):
            read_regular(path, 1 << 20)
    big = tmp_path / "big"
    big.write_bytes(b"x" * 2000)
    with pytest.raises(TooLarge, match="larger than 1 KiB"):
        read_regular(big, 1024)
    assert read_regular(big, 2000) == b"x" * 2000
