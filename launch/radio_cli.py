"""``fleet radio``: measured radio sites (docs/guides/radio-measured.md). ``sites`` lists the registry's,
``fetch NAME [--mirror URL|DIR]`` downloads one into the user cache (the map fetching of ``world/fetch.py``: the
same deadlines, refusals and clean-up), ``fit SITE`` fits the signal model to the site's readings and prints the
table of every model's errors (``--out PROFILE.toml`` keeps one model as a profile a scenario can name), and
``predict PROFILE --site SITE --points CSV`` gives a profile's received power at each anchor for any point.

Bad input (an unknown site, a file with a missing column or a position that is not a number, an anchor outside
the walls' box, a point outside the flat, a profile with an unknown key or a value out of range) is one line on
stderr and exit 2.
"""

from __future__ import annotations

import argparse
import io
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from fleet_emu.core.errors import ConfigError
from fleet_emu.launch.signals import sigterm_unwinds

if TYPE_CHECKING:
    from fleet_emu.core.radio_profile import RadioProfile
    from fleet_emu.netem.fit import Readings, Score
    from fleet_emu.world.sites import Site

MIRROR_HELP = ("read the files from a mirror laid out as MIRROR/<site name>/<upstream file name>: a folder, or a "
               "base URL (http:// or https://)")
#: The rows of the fit table: (model, one P0 per anchor).
ROWS: tuple[tuple[str, bool], ...] = (("defaults", False), ("cost231", False), ("log-distance", False),
                                      ("wall", False), ("log-distance", True), ("wall", True))
LABELS = {"defaults": "today's defaults", "cost231": "COST 231 multi-wall", "log-distance": "log-distance",
          "wall": "wall (eq. 4)"}


def add_parser(sub: Any) -> None:
    """The ``radio`` subcommand of ``fleet`` and its ``sites``, ``fetch``, ``fit`` and ``predict``."""
    r = sub.add_parser("radio", help="measured radio sites: list, fetch, fit the signal model, predict",
                       description="Measured radio sites (docs/guides/radio-measured.md): `sites` lists the "
                                   "registry's, `fetch` downloads one, `fit` fits the signal model to its readings, "
                                   "`predict` applies a fitted profile to points.")
    rsub = r.add_subparsers(dest="radio_command", metavar="{sites,fetch,fit,predict}")
    rsub.add_parser("sites", help="list the registry's measured sites, each 'fetched' or the command that fetches it")
    f = rsub.add_parser("fetch", help="download a measured site into the user cache, checked against its sha256")
    f.add_argument("name", metavar="NAME", help="a registry site (see `fleet radio sites`)")
    f.add_argument("--mirror", metavar="URL|DIR", help=MIRROR_HELP)
    f.add_argument("--force", action="store_true", help="download again even when the cached copy is intact")
    fit = rsub.add_parser("fit", help="fit the signal model to a site's readings and print every model's errors")
    fit.add_argument("site", metavar="SITE", help="a fetched registry site, or a folder holding anchors.csv, "
                                                  "layout.csv and readings.csv")
    fit.add_argument("--out", type=Path, metavar="PROFILE.toml", help="write the chosen model as a radio profile")
    fit.add_argument("--model", choices=("wall", "log-distance"), default="wall",
                     help="the model --out holds (default wall)")
    fit.add_argument("--per-anchor", action="store_true", help="--out holds the fit with one P0 per anchor")
    fit.add_argument("--plots", type=Path, metavar="DIR",
                     help="write measured-against-predicted and residual PNGs into DIR")
    _geometry_flags(fit)
    fit.add_argument("--folds", type=int, default=5, metavar="K", help="cross-validation folds, 2 to 50 (default 5)")
    fit.add_argument("--block", type=float, default=1.0, metavar="M",
                     help="cross-validation block side in metres, within [0.1, 100] (default 1)")
    p = rsub.add_parser("predict", help="a profile's received power at each anchor of a site, for given points")
    p.add_argument("profile", type=Path, metavar="PROFILE", help="a profile `fleet radio fit --out` wrote")
    p.add_argument("--site", required=True, metavar="SITE", help="the site whose anchors and walls to use")
    p.add_argument("--points", required=True, type=Path, metavar="POINTS.csv",
                   help="a CSV with columns x,y (metres, the site's frame); other columns are passed through")
    p.add_argument("--out", type=Path, metavar="OUT.csv", help="where to write the CSV (default: stdout)")


def _geometry_flags(p: argparse.ArgumentParser) -> None:
    p.add_argument("--resolution", type=float, default=0.05, metavar="M",
                   help="the grid cell the walls are drawn on, within [0.001, 1] m (default 0.05)")
    p.add_argument("--tag-height", type=float, metavar="M",
                   help="the transmitter's height for readings without a z column (default: the registry's, 1.3 m "
                        "for kolakowski-ble-2021; 0 for a folder)")


def cmd_radio(args: argparse.Namespace, out: TextIO | None = None) -> int:
    """``fleet radio ...``; the exit code. Errors are FleetErrors (exit 2)."""
    out = out or sys.stdout
    command = getattr(args, "radio_command", None)
    if command == "fetch":
        return fetch_site(args.name, mirror=args.mirror, force=args.force, out=out)
    if command == "fit":
        return cmd_fit(args, out)
    if command == "predict":
        return cmd_predict(args, out)
    list_sites(out)
    return 0


def list_sites(out: TextIO) -> None:
    """Every registry site, its source, licence and state (fetched, or the command that fetches it)."""
    from fleet_emu.world.registry import cache_dir
    from fleet_emu.world.sites import fetch_command, is_fetched, sites

    print(f"measured radio sites (fetched once into {cache_dir('radio')}):", file=out)
    for name, entry in sites().items():
        state = "fetched" if is_fetched(name) else f"`{fetch_command(name)}`"
        print(f"  {name:20s} {entry.repo}, {entry.licence.split(' (')[0]}: {state}", file=out)
        print(f"  {'':20s} {entry.description}", file=out)
        print(f"  {'':20s} cite: {entry.citation}", file=out)


def fetch_site(name: str, *, mirror: str | None = None, force: bool = False, out: TextIO | None = None) -> int:
    """Fetch the registry site ``name`` into the cache, saying where it came from and its licence."""
    from fleet_emu.world.fetch import fetch
    from fleet_emu.world.sites import lookup_site

    out = out or sys.stdout
    entry = lookup_site(name)
    with sigterm_unwinds():
        done = fetch(entry, mirror, force=force)
    files = ", ".join(f.path for f in entry.files)
    via = "" if done.cached or mirror is None else f" via {mirror}"
    where = f"already in {done.folder}" if done.cached else f"-> {done.folder}"
    print(f"{entry.name}: {entry.source} {files}{via} {where} (sha256 checked); licence {entry.licence}; cite "
          f"{entry.citation}", file=out)
    return 0


def site_links(spec: str, resolution: float, tag_height: float | None) -> tuple[Site, Readings, int]:
    """The site ``spec`` read, drawn at ``resolution`` and its readings as links; and how many positions were
    counted from a nearby free cell."""
    from fleet_emu.netem.fit import links
    from fleet_emu.world.site_grid import draw, geometry
    from fleet_emu.world.sites import load_site

    if tag_height is not None and not (math.isfinite(tag_height) and 0 <= tag_height <= 1000):
        raise ConfigError(f"--tag-height must be within [0, 1000] m (got {tag_height!r})")
    site = load_site(spec, tag_height)
    grid = draw(site.layout, resolution)
    geo = geometry(grid, site.anchors, site.xy, site.z)
    return site, links(geo.distance, geo.walls, site.rss, site.xy), geo.moved


def fit_scores(lk: Readings, folds: int, block: float) -> list[Score]:
    """Every row of :data:`ROWS`, fitted and scored."""
    from fleet_emu.netem.fit import score

    return [score(model, lk, per_anchor, block, folds) for model, per_anchor in ROWS]


def fit_table(scores: Sequence[Score]) -> str:
    """The fit table, Markdown (as the terminal and the docs page show it)."""
    head = ("| model | P0 (dBm at 1 m) | n | dB per wall | cap C | fitted | RMSE (dB) | CV RMSE (dB) | "
            "residual std (dB) | 1/e corr. (m) | correlated std (dB) | its 1/e (m) |")
    lines = [head, "| " + " | ".join(["---"] * 12) + " |"]
    for s in scores:
        f = s.fit
        label = LABELS[f.model] + (", P0 per anchor" if f.per_anchor else "")
        p0 = (f"{f.p0_mean:.1f} ({min(f.p0):.1f} to {max(f.p0):.1f})" if f.per_anchor else f"{f.p0_mean:.1f}")
        cap = "none" if f.max_walls is None else ("-" if f.model == "log-distance" else str(f.max_walls))
        waf = "-" if f.model == "log-distance" else f"{f.waf:.2f}"
        lines.append(f"| {label} | {p0} | {f.path_loss:.2f} | {waf} | {cap} | {f.fitted} | {s.rmse:.2f} | "
                     f"{s.cv_rmse:.2f} | {s.residual_std:.2f} | {s.correlation_m:.2f} | {s.shadow_std:.2f} | "
                     f"{s.shadow_m:.2f} |")
    return "\n".join(lines)


def comparison(scores: Sequence[Score], lk: Readings, block: float) -> str:
    """The wall model against log-distance, cross-validated, paired by reading, with a block-bootstrap 95 %
    interval."""
    from fleet_emu.netem.fit import block_ids, paired_gain

    by = {(s.fit.model, s.fit.per_anchor): s for s in scores}
    blocks = block_ids(lk.xy, block)[lk.point]
    out = []
    for per_anchor in (False, True):
        wall, logd = by[("wall", per_anchor)], by[("log-distance", per_anchor)]
        gain, lo, hi = paired_gain(logd.cv_errors, wall.cv_errors, blocks)
        which = "one P0 per anchor" if per_anchor else "one P0"
        out.append(f"wall vs log-distance ({which}): cross-validated RMSE {wall.cv_rmse:.2f} vs {logd.cv_rmse:.2f} "
                   f"dB, {gain:.2f} dB lower (95 % interval {lo:.2f} to {hi:.2f}, bootstrap over "
                   f"{int(blocks.max()) + 1} blocks, n = {len(lk.rss)} readings)")
    return "\n\n".join(out)


def fit_report(site: Site, lk: Readings, moved: int, resolution: float, folds: int, block: float,
               scores: Sequence[Score]) -> str:
    """What ``fleet radio fit`` prints: the site, how it was scored, the table and the comparison."""
    head = (f"site {site.name}: {len(site.anchor_ids)} anchors, {len(site.xy)} positions, {lk.rss.size} readings "
            f"(RSS in dBm); walls drawn on a {resolution:g} m grid, {moved} positions on a wall cell counted from "
            f"the nearest free one; cross-validation: {folds} folds of {block:g} m square blocks")
    return f"{head}\n\n{fit_table(scores)}\n\n{comparison(scores, lk, block)}\n"


def cmd_fit(args: argparse.Namespace, out: TextIO) -> int:
    """``fleet radio fit``: the table, and the profile with ``--out``."""
    if not 2 <= args.folds <= 50:
        raise ConfigError(f"--folds must be from 2 to 50 (got {args.folds})")
    if not (math.isfinite(args.block) and 0.1 <= args.block <= 100):
        raise ConfigError(f"--block must be within [0.1, 100] m (got {args.block!r})")
    site, lk, moved = site_links(args.site, args.resolution, args.tag_height)
    scores = fit_scores(lk, args.folds, args.block)
    report = fit_report(site, lk, moved, args.resolution, args.folds, args.block, scores)
    print(report, file=out, end="")
    if args.plots is not None:
        from fleet_emu.launch.radio_plots import write_plots

        try:
            written = write_plots(args.plots, scores, lk, report, site.name)
        except OSError as exc:
            raise ConfigError(f"cannot write the plots into {args.plots}: {exc.strerror or exc}") from None
        print("plots: " + ", ".join(map(str, written)), file=out)
    if args.out is not None:
        chosen = next(s for s in scores if s.fit.model == args.model and s.fit.per_anchor == args.per_anchor)
        write_profile(args.out, chosen, site, lk, args.resolution, args)
        print(f"profile ({args.model}{', P0 per anchor' if args.per_anchor else ''}) written to {args.out}",
              file=out)
    return 0


def profile_of(s: Score, site: Site, lk: Readings, resolution: float) -> RadioProfile:
    """The profile of a scored fit: its values, the weakest reading as the sensitivity, the site's tag height."""
    from fleet_emu.core.radio_profile import ProfileValues, RadioProfile

    f = s.fit
    values = ProfileValues(model=f.model, p0_dbm=round(f.p0_mean, 4), path_loss=round(f.path_loss, 4),
                           waf=round(f.waf, 4), max_walls=int(f.max_walls or 0),
                           sensitivity_dbm=float(math.floor(float(lk.rss.min()))),
                           tag_height=float(site.z.mean()), resolution=resolution)
    return RadioProfile(values, site=site.name,
                        anchor_p0_dbm=tuple(round(p, 4) for p in f.p0) if f.per_anchor else ())


def write_profile(path: Path, s: Score, site: Site, lk: Readings, resolution: float, args: argparse.Namespace) -> None:
    """The profile file, what the fit scored as comment lines above it."""
    from fleet_emu.core.files import write_atomic
    from fleet_emu.core.radio_profile import profile_text
    from fleet_emu.core.version import __version__

    flags = f" --model {args.model}" + (" --per-anchor" if args.per_anchor else "")
    header = [f"A radio profile: `fleet radio fit {args.site}{flags}` (fleet-emu {__version__}), "
              f"{s.readings} readings.",
              f"RMSE {s.rmse:.2f} dB, cross-validated {s.cv_rmse:.2f} dB ({args.folds} folds, {args.block:g} m "
              f"blocks); residual std {s.residual_std:.2f} dB, 1/e correlation {s.correlation_m:.2f} m;",
              f"correlated part of the residuals: std {s.shadow_std:.2f} dB, 1/e at {s.shadow_m:.2f} m.",
              "sensitivity_dbm: the weakest reading in the site's readings. Use: [radio] profile = \"THIS.toml\", "
              "or fleet run --radio-profile THIS.toml."]
    text = profile_text(profile_of(s, site, lk, resolution), header)
    try:
        write_atomic(path, lambda tmp: tmp.write_text(text))
    except OSError as exc:
        raise ConfigError(f"cannot write {path}: {exc.strerror or exc}") from None


def cmd_predict(args: argparse.Namespace, out: TextIO) -> int:
    """``fleet radio predict``: the points' CSV with a ``pred_<id>`` column per anchor."""
    from fleet_emu.core.radio_profile import load_profile

    profile = load_profile(args.profile)
    text = predict_csv(profile, args.site, args.points)
    if args.out is None:
        out.write(text)
        return 0
    from fleet_emu.core.files import write_atomic

    try:
        write_atomic(args.out, lambda tmp: tmp.write_text(text))
    except OSError as exc:
        raise ConfigError(f"cannot write {args.out}: {exc.strerror or exc}") from None
    return 0


def predict_csv(profile: RadioProfile, spec: str, points: Path) -> str:
    """The CSV of ``points`` (its columns kept) with the profile's RSS at each anchor of the site ``spec``; a
    one-line ConfigError for a point outside the site's walls."""
    import csv

    import numpy as np

    from fleet_emu.netem.fit import Fit, predict
    from fleet_emu.world.site_grid import draw, geometry, inside
    from fleet_emu.world.sites import load_site, numbers, read_text, table

    v = profile.values
    site = load_site(spec, v.tag_height)
    where = str(points)
    header, body = table(read_text(points), where, ("x", "y"))
    xy = np.stack([numbers(body, header.index(k), where, k) for k in ("x", "y")], axis=1)
    z = numbers(body, header.index("z"), where, "z") if "z" in header else np.full(len(xy), v.tag_height)
    out_of = np.flatnonzero(~inside(site.layout, xy))
    if len(out_of):
        i = int(out_of[0])
        raise ConfigError(f"{where} row {i + 2}: the point ({xy[i, 0]:g}, {xy[i, 1]:g}) is outside the walls of "
                          f"site {site.name} ({len(out_of)} such points)")
    geo = geometry(draw(site.layout, v.resolution), site.anchors, xy, z)
    f = Fit(v.model, bool(profile.anchor_p0_dbm), profile.p0_of(len(site.anchor_ids)), v.path_loss, v.waf,
            v.max_walls, fitted=0)
    n = len(site.anchor_ids)
    pred = predict(f, np.tile(np.arange(n), (len(xy), 1)), geo.distance, geo.walls)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([*header, *(f"pred_{i}" for i in site.anchor_ids)])
    for row, p in zip(body, pred, strict=True):
        w.writerow([*row, *(f"{x:.2f}" for x in p)])
    return buf.getvalue()
