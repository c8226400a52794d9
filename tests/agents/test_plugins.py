"""Allocators from installed packages (the ``fleet_emu.allocators`` entry-point group) and the scenario fields
an allocator declares. A plugin is "installed" the way pip leaves it: a module and a ``*.dist-info`` folder
with ``entry_points.txt`` on ``sys.path``, which ``importlib.metadata`` reads."""

from __future__ import annotations

import sys
import textwrap
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from fleet_emu.agents.allocators import Allocator, allocator_class, allocator_names, make_allocator, registry
from fleet_emu.agents.allocators.conformance import api_test, seed_test
from fleet_emu.agents.brain import allocator_config
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.scenario import RadioConfig, Scenario
from tests.harness.cli import run_cli

Install = Callable[[dict[str, str], dict[str, str]], None]

# A plugin allocator: the reachable cluster with the most cells, ties to the nearer one, then the lower index.
LARGEST = """
from fleet_emu.agents.allocators import Allocation, Allocator, Param


class Largest(Allocator{registration}):
    parameters = {{"weight": Param(0.0, ge=0), "reach": Param(10.0, gt=0)}}
    scenario_fields = {{"reach": "sensor_cells"}}

    def allocate(self, problem, inbox=()):
        me = problem.poses[problem.me]
        best = None
        for j, (cluster, wf) in enumerate(zip(problem.clusters, problem.wavefronts)):
            if wf[me] >= 0:
                key = (-cluster.size + self.weight * wf[me], wf[me], j)
                best = key if best is None or key < best else best
        return Allocation.none() if best is None else Allocation.assigned(problem, best[2])
"""


@pytest.fixture
def install(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Install]:
    """``install(modules, entry_points)``: write the modules and one distribution's entry points into a
    folder on sys.path, with the registry forgetting what it found before (and restored afterwards)."""
    monkeypatch.setattr(Allocator, "registry", dict(Allocator.registry))
    monkeypatch.setattr(registry, "_plugins", None)
    monkeypatch.setattr(registry, "_broken", {})
    monkeypatch.syspath_prepend(str(tmp_path))
    written: list[str] = []

    def _install(modules: dict[str, str], entry_points: dict[str, str]) -> None:
        for name, source in modules.items():
            (tmp_path / f"{name}.py").write_text(textwrap.dedent(source))
            written.append(name)
        dist = tmp_path / "test_plugins-0.1.dist-info"
        dist.mkdir()
        (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: test-plugins\nVersion: 0.1\n")
        lines = "".join(f"{name} = {target}\n" for name, target in entry_points.items())
        (dist / "entry_points.txt").write_text(f"[{registry.GROUP}]\n{lines}")

    yield _install
    for name in written:
        sys.modules.pop(name, None)


def test_a_plugin_is_found_loaded_on_demand_and_conforms(install: Install) -> None:
    install({"plug_largest": LARGEST.format(registration=', plugin_name="largest"')},
            {"largest": "plug_largest:Largest"})
    assert "largest" in allocator_names() and "minpos" in allocator_names()
    assert "plug_largest" not in sys.modules  # listed, not imported
    alloc = make_allocator({"type": "largest", "weight": 0.5})
    assert type(alloc).__module__ == "plug_largest"
    assert alloc.to_dict() == {"type": "largest", "weight": 0.5, "reach": 10.0}
    api_test({"type": "largest"})
    seed_test({"type": "largest", "weight": 1.0})
    with pytest.raises(ConfigError, match="'largest': weight must be >= 0"):
        make_allocator({"type": "largest", "weight": -1})


def test_a_class_without_plugin_name_takes_the_entry_point_name(install: Install) -> None:
    install({"plug_anon": LARGEST.format(registration="")}, {"biggest": "plug_anon:Largest"})
    assert "biggest" not in Allocator.registry
    assert make_allocator({"type": "biggest"}).to_dict()["type"] == "biggest"
    assert Allocator.registry["biggest"].__module__ == "plug_anon"


def test_a_plugin_subclassing_a_builtin_is_registered_under_its_own_name(install: Install) -> None:
    source = "from fleet_emu.agents.allocators.minpos import MinPos\n\nclass Mine(MinPos):\n    pass\n"
    install({"plug_sub": source}, {"mine": "plug_sub:Mine"})
    assert make_allocator({"type": "mine", "wavefront": "stop"}).to_dict() == {"type": "mine", "wavefront": "stop",
                                                                                   "replan": "tick"}
    assert make_allocator({"type": "minpos"}).to_dict()["type"] == "minpos"


def test_a_broken_plugin_fails_alone_once_and_in_one_line(install: Install, tmp_path: Path) -> None:
    trace = tmp_path / "imported"
    broken = f"""
    open({str(trace)!r}, "a").write("x")
    import no_such_dependency_of_the_plugin
    """
    install({"plug_broken": broken, "plug_ok": LARGEST.format(registration="")},
            {"broken": "plug_broken:Thing", "ok": "plug_ok:Largest"})
    assert make_allocator({"type": "minpos"}).to_dict()["type"] == "minpos"
    assert make_allocator({"type": "ok"}).to_dict()["type"] == "ok"
    assert not trace.exists()
    for _ in range(2):
        with pytest.raises(ConfigError) as exc:
            make_allocator({"type": "broken"})
        msg = str(exc.value)
        assert "'broken'" in msg and "plug_broken:Thing" in msg and "no_such_dependency_of_the_plugin" in msg
        assert "ModuleNotFoundError" in msg and "\n" not in msg
    assert trace.read_text() == "x"  # imported once
    assert "broken" in allocator_names()


def test_fleet_allocators_lists_plugins_and_broken_ones(install: Install) -> None:
    install({"plug_cli": LARGEST.format(registration="")}, {"big": "plug_cli:Largest", "gone": "plug_gone:X"})
    code, out, _ = run_cli(["allocators"])
    assert code == 0
    lines = {line.split()[0]: line for line in out.splitlines()}
    assert set(lines) == set(allocator_names())
    assert "(no description) [plugin plug_cli: weight=0.0 (>= 0), reach=<scenario sensor_cells> (> 0)]" in lines["big"]
    assert "failed to load: ModuleNotFoundError" in lines["gone"]
    assert "built-in: wavefront='full'" in lines["minpos"]


@pytest.mark.parametrize("source, target, match", [
    ("def thing():\n    pass\n", "thing", "is not an Allocator subclass"),
    (LARGEST.format(registration=', plugin_name="other"'), "Largest", "registers itself as 'other'"),
    (LARGEST.replace('"sensor_cells"', '"radio.no_such_field"').format(registration=""), "Largest",
     "'radio.no_such_field' is not a scenario field"),
    (LARGEST.replace('"reach": "sensor_cells"', '"range": "sensor_cells"').format(registration=""), "Largest",
     "'range', which is not a parameter"),
    (LARGEST.replace("Param(0.0, ge=0)", "Param(-1.0, ge=0)").format(registration=""), "Largest",
     "default of weight must be >= 0"),
    ("import dataclasses\nfrom fleet_emu.core.codec import Payload\n\n@dataclasses.dataclass(frozen=True)\n"
     "class Bid(Payload):\n    KIND = 'bid-old'\n    cost: int\n" + LARGEST.format(registration=""), "Largest",
     r"declared `class Bid\(Payload, kw_only=True, frozen=True\)`, not with @dataclasses.dataclass"),
])
def test_a_plugin_that_does_not_fit_is_a_config_error(source: str, target: str, match: str,
                                                      install: Install) -> None:
    install({"plug_misfit": source}, {"misfit": f"plug_misfit:{target}"})
    with pytest.raises(ConfigError, match=match) as exc:
        allocator_class("misfit")
    assert "allocator plugin 'misfit'" in str(exc.value)


def test_unknown_names_list_the_plugins_too(install: Install) -> None:
    install({}, {"someplugin": "not_imported:Cls"})
    with pytest.raises(ConfigError, match="unknown allocator 'telepathy'") as exc:
        make_allocator({"type": "telepathy"})
    assert "someplugin" in str(exc.value) and "minpos" in str(exc.value)


def test_scenario_fields_fill_what_the_config_leaves_out(install: Install) -> None:
    install({"plug_fields": LARGEST.format(registration="")}, {"fields": "plug_fields:Largest"})
    s = Scenario(sensor_range=3.0, cell_size=0.25, allocator={"type": "fields"})
    assert allocator_config(s) == {"type": "fields", "reach": 12.0}
    s = Scenario(sensor_range=3.0, cell_size=0.25, allocator={"type": "fields", "reach": 2.0})
    assert allocator_config(s) == {"type": "fields", "reach": 2.0}


def test_builtin_scenario_fields_are_the_radio_and_the_sensor() -> None:
    radio = RadioConfig(comm_range=6.0, path_loss=3.0, waf=2.5, max_walls=2)
    s = Scenario(cell_size=0.25, sensor_range=2.0, radio=radio, allocator={"type": "connectivity", "waf": 1.0})
    alloc = make_allocator(allocator_config(s))
    assert alloc.to_dict() == {"type": "connectivity", "alpha": 0.6, "beta": 0.4, "lam": 0.5, "comm_range": 6.0,
                               "cell_size": 0.25, "path_loss": 3.0, "waf": 1.0, "max_walls": 2,
                               "unknown_walls": False, "position": "without_self", "predict": "pose",
                               "replan": "tick"}
    s = Scenario(cell_size=0.25, sensor_range=2.0, allocator={"type": "utility"})
    assert allocator_config(s) == {"type": "utility", "sensor_range": 8.0}
    assert allocator_config(Scenario(allocator={"type": "minpos"})) == {"type": "minpos"}
    with pytest.raises(ConfigError, match="telepathy"):
        allocator_config(Scenario(allocator={"type": "telepathy"}))
