"""The rviz2 configuration shipped with the docs shows topics the bridge publishes, each with the display its
type needs and the durability its publisher offers (rviz2 itself cannot run here)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import yaml

from fleet_emu.ros2.fold import topics

RVIZ = Path(__file__).resolve().parents[2] / "docs" / "ros2" / "fleet_emu.rviz"
DISPLAY = {"nav_msgs/msg/OccupancyGrid": "rviz_default_plugins/Map",
           "geometry_msgs/msg/PoseStamped": "rviz_default_plugins/Pose",
           "nav_msgs/msg/Path": "rviz_default_plugins/Path",
           "visualization_msgs/msg/MarkerArray": "rviz_default_plugins/MarkerArray"}


def _displays(items: list[dict[str, Any]]) -> Iterator[dict[str, Any]]:
    for d in items:
        yield d
        yield from _displays(d.get("Displays", []))


def test_every_display_is_of_a_published_topic() -> None:
    conf = yaml.safe_load(RVIZ.read_text())
    manager = conf["Visualization Manager"]
    assert manager["Global Options"]["Fixed Frame"] == "map"
    published = topics(4)
    shown = [d for d in _displays(manager["Displays"]) if "Topic" in d]
    assert {d["Topic"]["Value"] for d in shown} == {t for t in published if t not in ("/clock", "/tf")}
    for d in shown:
        typename, latched = published[d["Topic"]["Value"]]
        assert d["Class"] == DISPLAY[typename]
        assert d["Topic"]["Durability Policy"] == ("Transient Local" if latched else "Volatile")
    assert any(d["Class"] == "rviz_default_plugins/TF" for d in _displays(manager["Displays"]))
