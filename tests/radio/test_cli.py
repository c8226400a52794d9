"""``fleet radio``: sites fetched through a mirror with the maps' machinery, a fit and a profile a run uses, a
prediction at every anchor for points inside the flat, and bad input as one line with exit code 2."""

from __future__ import annotations

import csv
import dataclasses
import io
from collections.abc import Callable
from pathlib import Path

import pytest

from fleet_emu.launch.cli import build_parser, main
from fleet_emu.launch.radio_cli import cmd_radio
from fleet_emu.launch.radio_plots import HISTOGRAM, SCATTER, carried_digest, digest
from fleet_emu.world.registry import cache_dir
from tests.harness.map_mirror import serve
from tests.radio.mirror import build_mirror, fetched
from tests.radio.synthetic import write_site

Fleet = Callable[..., "Done"]
PROFILE = ('model = "wall"\np0_dbm = -48.0\npath_loss = 1.0\nwaf = 9.0\nmax_walls = 1\nsensitivity_dbm = -93.0\n'
           'tag_height = 1.3\n')


@dataclasses.dataclass(frozen=True)
class Done:
    returncode: int
    stdout: str
    stderr: str


@pytest.fixture
def fleet(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> Fleet:
    """``fleet ARGS`` in this process, from ``tmp_path``, with a user cache of its own: exit code and output."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.chdir(tmp_path)

    def run(*argv: str) -> Done:
        with pytest.raises(SystemExit) as exc:
            main(list(argv))
        out, err = capsys.readouterr()
        return Done(int(exc.value.code or 0), out, err)

    return run


def radio(*argv: str) -> str:
    out = io.StringIO()
    assert cmd_radio(build_parser().parse_args(["radio", *argv]), out) == 0
    return out.getvalue()


def test_a_site_is_fetched_through_a_mirror_and_listed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert "`fleet radio fetch kolakowski-ble-2021`" in radio("sites")
    mirror = build_mirror(tmp_path / "mirror")
    line = radio("fetch", "kolakowski-ble-2021", "--mirror", str(mirror))
    assert "sha256 checked" in line and "CC BY 4.0" in line and "doi:10.3390/s21186270" in line
    assert sorted(p.name for p in (cache_dir("radio") / "kolakowski-ble-2021").iterdir()) == [
        "anchors.csv", "calibration_df.csv", "layout.csv"]
    assert "kolakowski-ble-2021  marckolak/ble-rss-fingerprints-calib2021, CC BY 4.0: fetched" in radio("sites")


def test_a_site_is_fetched_from_an_http_mirror(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    with serve(build_mirror(tmp_path / "mirror")) as url:
        line = radio("fetch", "kolakowski-ble-2021", "--mirror", url)
    assert f"via {url} -> " in line and "sha256 checked" in line
    assert "already in" in radio("fetch", "kolakowski-ble-2021")  # intact in the cache: nothing downloaded


def test_a_file_altered_in_the_mirror_is_refused_and_nothing_is_kept(tmp_path: Path, fleet: Fleet) -> None:
    mirror = tmp_path / "mirror" / "kolakowski-ble-2021"
    mirror.mkdir(parents=True)
    for name in ("anchors.csv", "layout.csv", "calibration_df.csv"):
        (mirror / name).write_text("id,x,y,z\n")
    done = fleet("radio", "fetch", "kolakowski-ble-2021", "--mirror", str(tmp_path / "mirror"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert "radio site kolakowski-ble-2021: anchors.csv from" in done.stderr and "not the registry's" in done.stderr
    assert not [p for p in (tmp_path / "xdg").rglob("*") if p.is_file()]


def test_predict_gives_every_anchor_inside_the_flat_and_one_line_outside(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fleet: Fleet) -> None:
    site = fetched(tmp_path, monkeypatch)
    (tmp_path / "p.toml").write_text(PROFILE)
    (tmp_path / "in.csv").write_text("x,y,label\n1.0,1.0,a\n4.5,3.5,b\n8.0,6.0,c\n")
    rows = list(csv.DictReader(io.StringIO(radio("predict", str(tmp_path / "p.toml"), "--site", site,
                                                 "--points", str(tmp_path / "in.csv")))))
    assert [r["label"] for r in rows] == ["a", "b", "c"]
    assert all(-120 < float(r[f"pred_{i}"]) < 0 for r in rows for i in range(1, 7))
    radio("predict", str(tmp_path / "p.toml"), "--site", site, "--points", str(tmp_path / "in.csv"),
          "--out", str(tmp_path / "out.csv"))
    head = (tmp_path / "out.csv").read_text().splitlines()[0]
    assert head == "x,y,label," + ",".join(f"pred_{i}" for i in range(1, 7))
    (tmp_path / "out_of.csv").write_text("x,y\n1.0,1.0\n8.0,1.0\n")
    done = fleet("radio", "predict", "p.toml", "--site", site, "--points", "out_of.csv")
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert "out_of.csv row 3: the point (8, 1) is outside the walls of site kolakowski-ble-2021" in done.stderr


def test_a_fit_writes_a_profile_a_run_uses(tmp_path: Path, fleet: Fleet) -> None:
    write_site(tmp_path / "mine", noise_db=1.0, points=120)
    done = fleet("radio", "fit", "mine/", "--out", "mine.toml", "--folds", "3", "--plots", "figs")
    assert done.returncode == 0, done.stderr
    report = done.stdout.split("plots: ")[0]
    assert {carried_digest(tmp_path / "figs" / name) for name in (SCATTER, HISTOGRAM)} == {digest(report)}
    assert "| wall (eq. 4) |" in done.stdout and "cross-validation: 3 folds of 1 m square blocks" in done.stdout
    assert "wall vs log-distance (one P0): cross-validated RMSE" in done.stdout
    assert "profile (wall) written to mine.toml" in done.stdout
    run = fleet("run", "--engine", "memory", "--robots", "2", "--max-ticks", "5", "--radio-profile", "mine.toml",
                "--no-record", "--quiet", "--out", "runs/r")
    assert run.returncode in (0, 3), run.stderr
    radio_cfg = (tmp_path / "runs" / "r" / "scenario.json").read_text()
    assert '"max_walls": 1' in radio_cfg and '"threshold": 0.0' in radio_cfg
    done = fleet("radio", "fit", "mine/", "--out", "logd.toml", "--model", "log-distance", "--per-anchor")
    assert done.returncode == 0 and "profile (log-distance, P0 per anchor) written to logd.toml" in done.stdout
    text = (tmp_path / "logd.toml").read_text()
    assert 'model = "log-distance"' in text and "waf = 0.0" in text and "anchor_p0_dbm = [" in text


@pytest.mark.parametrize(("argv", "message"), [
    (("radio", "fit", "nope"), "unknown radio site 'nope'"),
    (("radio", "fetch", "nope"), "unknown radio site 'nope'"),
    (("radio", "fit", "kolakowski-ble-2021"), "is not fetched: run `fleet radio fetch kolakowski-ble-2021`"),
    (("radio", "fit", "mine/", "--folds", "1"), "--folds must be from 2 to 50"),
    (("run", "--radio-profile", "absent.toml"), "radio profile absent.toml: no such file"),
])
def test_bad_input_is_one_line(tmp_path: Path, fleet: Fleet, argv: tuple[str, ...], message: str) -> None:
    write_site(tmp_path / "mine", points=20)
    done = fleet(*argv)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and message in done.stderr, done.stderr
