"""The generated parts of ``docs/guides/radio-measured.md``: the report of ``fleet radio fit kolakowski-ble-2021``
(between ``<!-- radio-fit: kolakowski-ble-2021 -->`` and ``<!-- /radio-fit -->``) and its two figures
(``docs/performance/img/radio-fit-*.png``), made by the tool itself with its defaults.

``python docs/radio_measured.py`` rewrites them from the fetched site (``fleet radio fetch kolakowski-ble-2021``
first); ``tests/radio/test_docs_page.py`` fails while the page or a figure is not what the tool gives.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "guides" / "radio-measured.md"
IMG = ROOT / "docs" / "performance" / "img"
BLOCK = re.compile(r"<!--\s*radio-fit:\s*(?P<site>[\w.-]+)\s*-->.*?<!--\s*/radio-fit\s*-->", re.S)


def fitted(site: str) -> tuple[str, Any, Any]:
    """The report ``fleet radio fit SITE`` prints with its defaults, its scores and links."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from fleet_emu.launch.radio_cli import fit_report, fit_scores, site_links
    from fleet_emu.netem.fit import BLOCK_M, FOLDS
    from fleet_emu.world.site_grid import DEFAULT_RESOLUTION

    site_data, lk, moved = site_links(site, DEFAULT_RESOLUTION, None)
    scores = fit_scores(lk, FOLDS, BLOCK_M)
    return fit_report(site_data, lk, moved, DEFAULT_RESOLUTION, FOLDS, BLOCK_M, scores), scores, lk


def block_of(markdown: str) -> tuple[str, str]:
    """The site the page's generated part is of, and that part's body."""
    m = BLOCK.search(markdown)
    if m is None:
        raise SystemExit(f"{PAGE} has no <!-- radio-fit: SITE --> part")
    body = m.group(0).split("-->", 1)[1].rsplit("<!--", 1)[0]
    return m["site"], body.strip("\n")


def refresh(markdown: str, report: str) -> str:
    """``markdown`` with its generated part holding ``report``."""
    return BLOCK.sub(lambda m: f"<!-- radio-fit: {m['site']} -->\n\n{report.strip()}\n\n<!-- /radio-fit -->",
                     markdown)


def main() -> int:
    """Rewrite the page's generated part and the figures from the fetched site."""
    from fleet_emu.launch.radio_plots import write_plots

    text = PAGE.read_text()
    site, _ = block_of(text)
    report, scores, lk = fitted(site)
    new = refresh(text, report)
    if new != text:
        PAGE.write_text(new)
        print(f"wrote {PAGE.relative_to(ROOT)}")
    for path in write_plots(IMG, scores, lk, report, site):
        print(f"wrote {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
