"""Small synthetic sites for the tests of pure logic: a 6 x 4 m room split by a 10 cm wall at x = 3 m with a
door, anchors on either side, readings drawn from a known wall model (seeded noise)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: The free space's outline: the room, the partition as a sliver (x 3.0..3.1) from y = 1 to the top wall.
LAYOUT = [(0.0, 0.0), (6.0, 0.0), (6.0, 4.0), (3.1, 4.0), (3.1, 1.0), (3.0, 1.0), (3.0, 4.0), (0.0, 4.0),
          (0.0, 0.0)]
ANCHORS = [(1, 1.0, 3.0, 2.0), (2, 5.0, 3.0, 2.5), (3, 2.0, 0.5, 1.5)]
#: The model the readings are drawn from: P0, exponent, dB per wall, cap.
TRUE = (-45.0, 2.2, 7.0, 1)


def write_site(folder: Path, *, noise_db: float = 0.0, seed: int = 0, points: int = 300,
               readings_text: str | None = None) -> Path:
    """The three files of the synthetic site in ``folder`` (readings from :data:`TRUE` with ``noise_db``
    Gaussian noise, or ``readings_text`` as given)."""
    from fleet_emu.world.site_grid import draw, geometry, inside

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "layout.csv").write_text("x,y\n" + "".join(f"{x},{y}\n" for x, y in LAYOUT))
    (folder / "anchors.csv").write_text("id,x,y,z\n" + "".join(f"{i},{x},{y},{z}\n" for i, x, y, z in ANCHORS))
    if readings_text is None:
        rng = np.random.default_rng(seed)
        layout = np.array(LAYOUT)
        xy = rng.uniform([0.2, 0.2], [5.8, 3.8], size=(points * 2, 2))
        xy = xy[inside(layout, xy) & ((xy[:, 0] < 2.9) | (xy[:, 0] > 3.2))][:points]
        anchors = np.array([a[1:] for a in ANCHORS])
        geo = geometry(draw(layout), anchors, xy, np.zeros(len(xy)))
        p0, n, waf, cap = TRUE
        rss = p0 - 10 * n * np.log10(geo.distance) - waf * np.minimum(geo.walls, cap)
        rss += rng.normal(0, noise_db, size=rss.shape) if noise_db else 0
        lines = ["x,y,rssi_1,rssi_2,rssi_3"] + [f"{x:.4f},{y:.4f}," + ",".join(f"{v:.3f}" for v in row)
                                                for (x, y), row in zip(xy, rss, strict=True)]
        readings_text = "\n".join(lines) + "\n"
    (folder / "readings.csv").write_text(readings_text)
    return folder
