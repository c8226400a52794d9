"""The Foxglove layout of a run, built with the ``foxglove-sdk`` package's layout types: one layout for a
recording (``run.mcap``) and a live run (``fleet run --live``), which carry the same topics.

A 3D panel (top-down, frame ``map``) with the scene (``/viz/scene``: robots, targets, radio links, the base),
the true map, the coverage and (hidden until ticked) each robot's belief; a plot of coverage, connected fraction
and, with a base station, base-connected fraction; a plot of each robot's decision time; a plot of the radio
counters of the tick; the log (``/viz/log``). ``fleet report --layout FILE`` writes it (``--robots N``: the robots
it plots, default 8; ``--base``: a live run with a base station).
"""

from __future__ import annotations

from pathlib import Path

import foxglove.layouts as fl

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.keys import robot_ids
from fleet_emu.recording.foxglove import FRAME, TOPIC_COVERAGE, TOPIC_LOG, TOPIC_SCENE, TOPIC_TRUTH, belief_topic
from fleet_emu.recording.stats import TOPIC_STATS

DEFAULT_ROBOTS = 8


def _grid(visible: bool = True) -> fl.BaseRendererGridTopicSettings:
    """The fold's grids carry RGBA bytes per cell (``red``, ``green``, ``blue``, ``alpha``)."""
    return fl.BaseRendererGridTopicSettings(visible=visible, color_mode="rgba-fields")


def _scene_panel(robots: list[str]) -> fl.ThreeDeePanel:
    topics: dict[str, fl.BaseRendererTopicSettings] = {
        TOPIC_SCENE: fl.BaseRendererSceneUpdateTopicSettings(visible=True),
        TOPIC_TRUTH: _grid(), TOPIC_COVERAGE: _grid(),
    }
    topics |= {belief_topic(r): _grid(visible=False) for r in robots}
    return fl.ThreeDeePanel(title="fleet", config=fl.ThreeDeeConfig(
        follow_tf=FRAME, topics=topics,
        camera_state=fl.ThreeDeeCameraState(perspective=False, distance=60.0, phi=0.0, theta_offset=0.0)))


def _plot(title: str, series: list[tuple[str, str]]) -> fl.PlotPanel:
    return fl.PlotPanel(title=title, config=fl.PlotConfig(
        paths=[fl.PlotSeries(value=path, label=label, enabled=True) for path, label in series], show_legend=True))


def layout(robots: int = DEFAULT_ROBOTS, base: bool = False) -> fl.Layout:
    """The layout for runs of up to ``robots`` robots (each one's decision time plotted, belief listed); the
    base-connected fraction is plotted only for a run with a base station (``base``): without one it is null."""
    ids = robot_ids(robots)
    team = _plot("coverage and connectivity", [
        (f"{TOPIC_STATS}.coverage", "coverage"), (f"{TOPIC_STATS}.connected_fraction", "connected fraction"),
        *([(f"{TOPIC_STATS}.base_connected_fraction", "base-connected (tick)")] if base else [])])
    decisions = _plot("decision time (ms)", [(f"{TOPIC_STATS}.robots.{r}.decision_ms", r) for r in ids])
    radio = _plot("radio (this tick)", [(f"{TOPIC_STATS}.radio.tick.{k}", k) for k in
                                        ("sent", "delivered", "dropped_loss", "dropped_signal")])
    log = fl.LogPanel(title="log", config=fl.LogConfig(topic_to_render=TOPIC_LOG))
    plots = fl.SplitContainer(direction="column", items=[
        fl.SplitItem(content=team), fl.SplitItem(content=decisions), fl.SplitItem(content=radio)])
    left = fl.SplitContainer(direction="column", items=[
        fl.SplitItem(proportion=3, content=_scene_panel(ids)), fl.SplitItem(proportion=1, content=log)])
    return fl.Layout(content=fl.SplitContainer(direction="row", items=[
        fl.SplitItem(proportion=3, content=left), fl.SplitItem(proportion=2, content=plots)]))


def layout_json(robots: int = DEFAULT_ROBOTS, base: bool = False) -> str:
    return layout(robots, base).to_json()


def write_layout(path: Path, robots: int | None = None, base: bool = False) -> None:
    """``fleet report --layout FILE``: the layout as JSON (a ConfigError for a bad robot count or an unwritable
    file); ``base``: the runs have a base station."""
    n = DEFAULT_ROBOTS if robots is None else robots
    if not 1 <= n <= 1024:
        raise ConfigError(f"--robots must be from 1 to 1024 (got {n})")
    try:
        path.write_text(layout_json(n, base) + "\n")
    except OSError as exc:
        raise ConfigError(f"cannot write the layout to {path}: {exc.strerror or exc}") from None
