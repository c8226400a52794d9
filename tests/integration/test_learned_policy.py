"""A learned policy (the ``policy`` allocator reading a weights file, as ``fleet_emu.rl`` saves one) runs in the
process fleet: ``fleet run --allocator policy --param path=FILE`` over processes at loss 0.3 gives the memory
engine's run for the seed; a bad parameter or file is one line."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import fleet_emu as fe
from fleet_emu.agents.allocators.policy import save_policy
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import deterministic
from tests.conftest import result, run_cli


def test_a_learned_policy_runs_in_the_process_fleet_as_in_memory(small_map: Path, tmp_path: Path) -> None:
    policy = tmp_path / "policy.npz"
    save_policy(policy, np.array([-1.0, 0.2, -0.6, 0.1, 0.5]))
    argv = ["run", "--map", str(small_map), "--robots", "3", "--seed", "2", "--loss", "0.3", "--max-ticks", "120",
            "--allocator", "policy", "--param", f"path={policy}", "--quiet", "--no-record"]
    code, _, err = run_cli([*argv, "--out", str(tmp_path / "p")])
    assert code in (0, 3), err
    over_processes = result(tmp_path / "p")
    assert over_processes["engine"] == "processes"
    assert over_processes["allocator_params"] == {"type": "policy", "path": str(policy)}
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
