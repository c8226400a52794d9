"""A learned policy (the ``policy`` allocator reading a weights file, as ``fleet_emu.rl`` saves one) runs in the
process fleet: ``fleet run --allocator policy --param path=FILE`` over processes at loss 0.3 gives the memory
engine's run for the seed; a bad parameter or file is one line. The file is untrusted: read once by the
launcher, its sha256 recorded in ``result.json`` and verified by every robot (one swapped after the launcher
read it is refused by the robots, not run), and a zip bomb, a lying zip, a device or weights that overflow are
refused before anything large is allocated."""

from __future__ import annotations

import hashlib
import io
import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest

import fleet_emu as fe
from fleet_emu.agents.allocators.policy import save_policy
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import deterministic
from tests.harness.cli import result, run_cli


@pytest.mark.slow  # a policy over processes; memory engine by default
def test_a_learned_policy_runs_in_the_process_fleet_as_in_memory(small_map: Path, tmp_path: Path) -> None:
    policy = tmp_path / "policy.npz"
    save_policy(policy, np.array([-1.0, 0.2, -0.6, 0.1, 0.5]))
    argv = ["run", "--map", str(small_map), "--robots", "3", "--seed", "2", "--loss", "0.3", "--max-ticks", "120",
            "--allocator", "policy", "--param", f"path={policy}", "--quiet", "--no-record"]
    code, _, err = run_cli([*argv, "--out", str(tmp_path / "p")])
    assert code in (0, 3), err
    over_processes = result(tmp_path / "p")
    assert over_processes["engine"] == "processes"
    sha256 = hashlib.sha256(policy.read_bytes()).hexdigest()
    assert over_processes["allocator_params"] == {"type": "policy", "path": str(policy), "sha256": sha256}
    s = fe.Scenario().override(map=str(small_map), robots=3, seed=2, loss=0.3, max_ticks=120,
                               allocator={"type": "policy", "path": str(policy)})
    in_memory = Fleet(s).run()
    assert deterministic(in_memory.data) == deterministic(over_processes)
    assert over_processes["radio"]["dropped_loss"] > 0 and over_processes["ticks"] > 0


def test_a_bad_policy_parameter_or_file_is_one_line(small_map: Path, tmp_path: Path) -> None:
    (tmp_path / "junk.npz").write_bytes(b"not a policy")
    common = ["run", "--map", str(small_map), "--engine", "memory", "--allocator", "policy", "--quiet"]
    for param, says in (("pathjunk", "NAME=VALUE"), (f"path={tmp_path / 'none.npz'}", "cannot read the policy"),
                        (f"path={tmp_path / 'junk.npz'}", "cannot read the policy"), ("k=3", "no parameter 'k'")):
        code, _, err = run_cli([*common, "--param", param, "--out", str(tmp_path / "x")])
        assert code == 2 and err.count("\n") == 1 and says in err, err
        assert not (tmp_path / "x").exists()


@pytest.mark.slow  # 2nd policy run over processes
def test_a_policy_swapped_after_the_launcher_read_it_is_refused_by_the_robots(
        small_map: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The adversary replaces the file between the launcher's check and the robots' load (here: right after the
    launcher's checks, before any robot starts): every robot reads the new bytes, finds another sha256 than the
    run's, and refuses; the run fails naming the change instead of running other weights."""
    from fleet_emu.launch import runner

    policy = tmp_path / "policy.npz"
    save_policy(policy, np.array([-1.0, 0.2, -0.6, 0.1, 0.5]))
    checked = runner.check

    def check_then_swap(scenario: fe.Scenario) -> object:
        map_data = checked(scenario)
        save_policy(policy, np.array([1.0, 0.0, 0.0, 0.0, 0.0]))  # the farthest frontier first: a worse policy
        return map_data

    monkeypatch.setattr(runner, "check", check_then_swap)
    code, _, err = run_cli(["run", "--map", str(small_map), "--robots", "2", "--max-ticks", "60", "--allocator",
                            "policy", "--param", f"path={policy}", "--quiet", "--no-record",
                            "--out", str(tmp_path / "run")])
    assert code == 1 and err.count("\n") == 1, err  # the run failed (how its end is named varies with timing)
    for robot in ("r0", "r1"):  # each robot refused, saying why in one line
        assert "changed since the run read it" in (tmp_path / "run" / f"{robot}.log").read_text().splitlines()[-1]
    res = result(tmp_path / "run")
    assert res["ticks"] == 0 and res["coverage"] < 0.5  # nothing explored: no robot ran the other weights
    assert res["allocator_params"]["sha256"] != hashlib.sha256(policy.read_bytes()).hexdigest()


def _npz(members: dict[str, bytes], compress: bool = True) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED) as z:
        for name, data in members.items():
            z.writestr(name, data)
    return buf.getvalue()


def _npy(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, array)
    return buf.getvalue()


def _good_members(weights: np.ndarray) -> dict[str, bytes]:
    from fleet_emu.agents.allocators.policy import FEATURES

    return {"weights.npy": _npy(weights), "k.npy": _npy(np.array(8, dtype=np.int64)),
            "features.npy": _npy(np.array(FEATURES))}


def _lying(data: bytes, name: str, size: int) -> bytes:
    """``data`` (a zip) with ``name``'s uncompressed size said to be ``size`` in both of its headers."""
    out = bytearray(data)
    raw = name.encode()
    for sig, offset in ((b"PK\x03\x04", 22), (b"PK\x01\x02", 24)):  # local header, central directory
        at = out.find(sig + b"")
        while at >= 0:
            name_at = at + (30 if sig == b"PK\x03\x04" else 46)
            if out[name_at:name_at + len(raw)] == raw:
                struct.pack_into("<I", out, at + offset, size)
            at = out.find(sig, at + 4)
    return bytes(out)


def test_a_bomb_a_lying_zip_a_device_or_overflowing_weights_are_refused_in_one_line(
        small_map: Path, tmp_path: Path) -> None:
    zeros = np.zeros(10_000_000, dtype=np.float64)  # 80 MB of weights in a file of about 80 kB
    bomb = _good_members(np.zeros(5)) | {"weights.npy": _npy(zeros)}
    del zeros
    files = {
        "bomb.npz": (_npz(bomb), "weights.npy would be"),
        "lying.npz": (_lying(_npz(bomb), "weights.npy", 1000), "not an .npz policy file"),
        "huge.npz": (_npz(_good_members(np.full(5, 1e308))), "every weight must be a finite number"),
        "nan.npz": (_npz(_good_members(np.array([np.nan, 0, 0, 0, 0]))), "every weight must be a finite number"),
        "pickled.npz": (_npz(_good_members(np.zeros(5)) | {"k.npy": _npy(np.array([{}], dtype=object))}),
                        "cannot read"),
        "extra.npz": (_npz(_good_members(np.zeros(5)) | {"more.npy": b"x"}), "is not a policy file"),
    }
    for name, (data, _) in files.items():
        (tmp_path / name).write_bytes(data)
    assert (tmp_path / "bomb.npz").stat().st_size < 1 << 20  # under the file's own limit: the members are checked
    cases = [(str(tmp_path / n), says) for n, (_, says) in files.items()]
    cases += [("/dev/zero", "not a regular file (a device)"), (str(tmp_path), "not a regular file (a folder)")]
    common = ["run", "--map", str(small_map), "--engine", "memory", "--allocator", "policy", "--quiet"]
    for path, says in cases:
        code, _, err = run_cli([*common, "--param", f"path={path}", "--out", str(tmp_path / "x")])
        assert code == 2 and err.count("\n") == 1 and says in err, (path, err)
        assert not (tmp_path / "x").exists()
