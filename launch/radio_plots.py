"""The figures of ``fleet radio fit --plots DIR``: measured against predicted received power, and the residuals'
histogram, of the wall model and of log-distance (one P0 each). Each PNG carries the digest of the report it
was drawn with (its ``Description`` text chunk), so that a page showing it can be checked against the tool
(``tests/radio/test_docs_page.py``)."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fleet_emu.launch.radio_cli import LABELS
from fleet_emu.netem.fit import Readings, Score, predict

#: The figures' file names in the folder given.
SCATTER, HISTOGRAM = "radio-fit-scatter.png", "radio-fit-residuals.png"


def digest(report: str) -> str:
    """The digest a figure carries of the report it goes with."""
    return "fleet radio fit " + hashlib.sha256(report.encode()).hexdigest()[:16]


def _pair(scores: Sequence[Score]) -> list[Score]:
    return [s for s in scores if not s.fit.per_anchor and s.fit.model in ("log-distance", "wall")]


def write_plots(folder: Path, scores: Sequence[Score], lk: Readings, report: str, site: str) -> list[Path]:
    """The two PNGs in ``folder``; their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    meta = {"Description": digest(report), "Software": "fleet-emu"}
    pair = _pair(scores)
    fig, axes = plt.subplots(1, len(pair), figsize=(10, 4.6), sharex=True, sharey=True)
    lo, hi = float(lk.rss.min()) - 2, float(lk.rss.max()) + 2
    for ax, s in zip(np.atleast_1d(axes), pair, strict=True):
        pred = predict(s.fit, lk.anchor, lk.distance, lk.walls)
        ax.hexbin(pred, lk.rss, gridsize=45, bins="log", cmap="viridis", extent=(lo, hi, lo, hi), mincnt=1)
        ax.plot([lo, hi], [lo, hi], color="tab:red", lw=1)
        ax.set_title(f"{LABELS[s.fit.model]}: RMSE {s.rmse:.2f} dB, CV {s.cv_rmse:.2f} dB", fontsize=10)
        ax.set_xlabel("predicted RSS (dBm)")
    np.atleast_1d(axes)[0].set_ylabel("measured RSS (dBm)")
    fig.suptitle(f"{site}: {len(lk.rss)} readings (data: Kolakowski 2021, CC BY 4.0)" if "kolakowski" in site
                 else f"{site}: {len(lk.rss)} readings", fontsize=10)
    fig.tight_layout()
    scatter = folder / SCATTER
    fig.savefig(scatter, dpi=90, metadata=meta)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(7, 4))
    edges = [float(e) for e in np.arange(-30, 30.5, 1.0)]
    for s in pair:
        ax.hist(np.clip(s.residuals, -30, 30), bins=edges, histtype="step", lw=1.5,
                label=f"{LABELS[s.fit.model]} (std {s.residual_std:.2f} dB)")
    ax.set_xlabel("measured less predicted (dB)")
    ax.set_ylabel("readings")
    ax.legend(fontsize=9)
    ax.set_title(f"{site}: residuals", fontsize=10)
    fig.tight_layout()
    hist = folder / HISTOGRAM
    fig.savefig(hist, dpi=90, metadata=meta)
    plt.close(fig)
    return [scatter, hist]


def carried_digest(png: Path) -> str | None:
    """The digest a PNG carries (None when it has none)."""
    from PIL import Image

    with Image.open(png) as im:
        text = getattr(im, "text", {}) or {}
        value = text.get("Description")
        return value if isinstance(value, str) else None
