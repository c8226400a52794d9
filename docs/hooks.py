"""The reference pages' generated parts, written into the pages themselves so that they read the same on the
repository as on the site; an MkDocs hook (mkdocs.yml ``hooks``) refreshes them again when the site is built.

Each generated part sits between an opening and a closing comment, and ``python docs/hooks.py`` rewrites it
(``tests/test_docs_generated.py`` fails while a page is not current):

- ``<!-- cli-help: run -->`` ... ``<!-- /cli-help -->``: the help text of ``fleet run`` (``<!-- cli-help: -->``:
  of ``fleet``), from the parser itself, so that the CLI reference cannot drift from the code.
- ``<!-- api -->`` ... ``<!-- /api -->``: a section per name of ``fleet_emu.__all__``, grouped as its source
  groups them (a comment line per group), from the docstrings of the module that defines each.
- ``<!-- doc: fleet_emu.core.messages.Links -->`` ... ``<!-- /doc -->``: one class's or function's section.
- ``<!-- claims: bautin-fig5 -->`` ... ``<!-- /claims -->``: a paper study's claims, judged with their intervals
  by the tool itself on the study's results kept in ``docs/performance/claims/NAME`` (``python docs/hooks.py
  --keep RESULTS`` keeps them), so that the papers page cannot say other than the tool.

Docstrings are written in one style, reStructuredText's as Sphinx reads it (``literal``, ``:class:`Name```,
``:func:`name```, a ``::`` paragraph before an indented example), the style mkdocs.yml gives mkdocstrings
(``docstring_style: sphinx``); :func:`markdown_of` turns it into Markdown: a role becomes inline code and an
indented example a fenced block.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import inspect
import io
import json
import os
import re
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: The pages holding generated parts.
PAGES = ("reference/cli.md", "reference/api.md", "reference/protocol.md", "performance/papers.md")
CLI_HELP = re.compile(r"<!--\s*cli-help:\s*(?P<arg>[\w-]*)\s*-->.*?<!--\s*/cli-help\s*-->", re.S)
API = re.compile(r"<!--\s*api\s*-->(?P<arg>).*?<!--\s*/api\s*-->", re.S)
DOC = re.compile(r"<!--\s*doc:\s*(?P<arg>[\w.]+)\s*-->.*?<!--\s*/doc\s*-->", re.S)
CLAIMS = re.compile(r"<!--\s*claims:\s*(?P<arg>[\w.-]+)\s*-->.*?<!--\s*/claims\s*-->", re.S)
MEANS = re.compile(r"<!--\s*means:\s*(?P<arg>[\w.-]+)\s*-->.*?<!--\s*/means\s*-->", re.S)
#: Where a paper study's results are kept for the claims tables (``python docs/hooks.py --keep RESULTS``).
KEPT = ROOT / "docs" / "performance" / "claims"
#: The columns of a sweep's rows that the claims read (the rest are left out of the kept copy).
KEPT_COLUMNS = ("id", "status", "completed", "ticks", "coverage", "connected_fraction", "path_length", "robots",
                "map", "comm", "loss_applied", "map_sync", "scenario.map_sync", "scenario.radio.bandwidth",
                "base_connected_fraction.overall", "radio.bytes_sent")
ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|exc|obj|const|ref):`~?\.?([^`]+)`")


def cli_help(command: str) -> str:
    """The ``--help`` text of ``fleet COMMAND`` (of ``fleet`` for an empty one), 100 columns wide."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from fleet_emu.cli import build_parser

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"
    try:
        parser = build_parser()
        if command:
            sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
            parser = sub.choices[command]
        with contextlib.redirect_stdout(io.StringIO()):
            text = parser.format_help()
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old
    return text


def markdown_of(doc: str) -> str:
    """A docstring (reStructuredText as Sphinx reads it) as Markdown: roles as inline code, ``::`` examples
    fenced."""
    out: list[str] = []
    lines = inspect.cleandoc(doc).splitlines()
    i = 0
    while i < len(lines):
        line = ROLE.sub(r"``\1``", lines[i])
        if line.rstrip().endswith("::"):
            out.append(line.rstrip()[:-1] if not line.rstrip().endswith(" ::") else line.rstrip()[:-3])
            i += 1
            block: list[str] = []
            while i < len(lines) and (not lines[i].strip() or lines[i].startswith(" ")):
                block.append(lines[i])
                i += 1
            while block and not block[-1].strip():
                block.pop()
            body = inspect.cleandoc("\n".join(block)) if block else ""
            out += ["", "```text", body, "```", ""]
            continue
        out.append(line)
        i += 1
    return "\n".join(out).strip()


def _signature(obj: Any, name: str) -> str:
    """``name(params) -> ret`` of a function or a class's constructor, a parameter a line when long."""
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):
        return name
    params: list[str] = []
    written = _written_annotations(obj)
    for p in sig.parameters.values():
        if p.name in ("self", "cls"):
            continue
        if p.kind is p.KEYWORD_ONLY and not any(q.startswith("*") for q in params):
            params.append("*")
        params.append(_param(p.replace(annotation=written[p.name]) if p.name in written else p))
    ret = "" if sig.return_annotation is inspect.Signature.empty or inspect.isclass(obj) else \
        f" -> {_annotation(sig.return_annotation)}"
    one = f"{name}({', '.join(params)}){ret}"
    if len(one) <= 100:
        return one
    return f"{name}(\n" + "".join(f"    {p},\n" for p in params) + f"){ret}"


def _written_annotations(obj: Any) -> dict[str, str]:
    """A class's field annotations as its source writes them (a msgspec struct's signature has them evaluated)."""
    if not inspect.isclass(obj):
        return {}
    out: dict[str, str] = {}
    for base in reversed(obj.__mro__):
        out.update({k: v for k, v in vars(base).get("__annotations__", {}).items() if isinstance(v, str)})
    return out


def _annotation(a: Any) -> str:
    return a if isinstance(a, str) else inspect.formatannotation(a)


def _param(p: inspect.Parameter) -> str:
    """One parameter as written in the source: ``name: type = default`` (``*args``, ``**kwargs``)."""
    star = {p.VAR_POSITIONAL: "*", p.VAR_KEYWORD: "**"}.get(p.kind, "")
    text = star + p.name
    if p.annotation is not p.empty:
        text += f": {_annotation(p.annotation)}"
    if p.default is not p.empty:
        text += f" = {p.default!r}" if p.annotation is not p.empty else f"={p.default!r}"
    return text


def _members(cls: type) -> list[tuple[str, Any]]:
    """A class's own public methods and properties with a docstring, in source order."""
    out = []
    for name, value in vars(cls).items():
        if name.startswith("_"):
            continue
        fn = value.__func__ if isinstance(value, classmethod | staticmethod) else value
        if (inspect.isfunction(fn) or isinstance(fn, property)) and inspect.getdoc(fn):
            out.append((name, value))
    return out


def doc_section(path: str, level: int = 3, title: str | None = None) -> str:
    """The section of one class or function (``module.Name``): its heading, signature, docstring, and a
    class's own public methods and properties."""
    module, _, name = path.rpartition(".")
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    obj = getattr(importlib.import_module(module), name)
    head = "#" * level
    kind = "class " if inspect.isclass(obj) else "def " if callable(obj) else ""
    # ``py``, not ``python``: a signature is shown, not run (tests/test_docs.py runs ``python`` blocks)
    parts = [f"{head} `{title or name}`", "", "```py", kind + _signature(obj, name), "```", ""]
    parts += [markdown_of(inspect.getdoc(obj) or ""), ""]
    if inspect.isclass(obj) and not issubclass(obj, BaseException):
        for member, value in _members(obj):
            fn = value.__func__ if isinstance(value, classmethod | staticmethod) else value
            if isinstance(fn, property):
                sig = f"{member}  # property"
            else:
                sig = ("@classmethod\n" if isinstance(value, classmethod) else "") + "def " + _signature(fn, member)
            parts += [f"{head}# `{name}.{member}`", "", "```py", sig, "```", "",
                      markdown_of(inspect.getdoc(fn) or ""), ""]
    return "\n".join(parts).rstrip() + "\n"


def api_groups(root: Path = ROOT) -> list[tuple[str, list[str]]]:
    """``fleet_emu.__all__`` as its source lists it: (group comment, names) in order."""
    text = (root / "fleet_emu" / "__init__.py").read_text()
    body = text[text.index("__all__ = [") + len("__all__ = ["):]
    body = body[:body.index("]")]
    groups: list[tuple[str, list[str]]] = [("", [])]
    for line in body.splitlines():
        line = line.strip()
        if line.startswith("#"):
            groups.append((line.lstrip("# ").strip(), []))
        else:
            groups[-1][1].extend(re.findall(r'"([^"]+)"', line))
    return [(title, names) for title, names in groups if names]


def api_page() -> str:
    """A section per public name, from the module that defines it."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    import fleet_emu

    out = []
    for title, names in api_groups():
        out.append(f"## {(title or 'package').capitalize()}\n")
        for name in names:
            if name.startswith("__"):
                out.append(f"### `fleet_emu.{name}`\n\nThe installed package's version (`fleet-emu` on PyPI).\n")
                continue
            if name == "SCHEMA_VERSION":
                out.append(f"### `fleet_emu.{name}`\n\nThe version of the bus messages, `result.json` and the "
                           "recording layout (an integer).\n")
                continue
            module = fleet_emu._LAZY.get(name, "fleet_emu")
            out.append(doc_section(f"{module}.{name}", 3, f"fleet_emu.{name}"))
    return "\n".join(out)


def refresh(markdown: str) -> str:
    """``markdown`` with every generated part rewritten from the code."""
    def block(tag: str, arg: str, body: str) -> str:
        opener = f"<!-- {tag}: {arg} -->" if tag != "api" else "<!-- api -->"
        return f"{opener}\n\n{body.strip()}\n\n<!-- /{tag} -->"

    markdown = CLI_HELP.sub(lambda m: block("cli-help", m["arg"], f"```text\n{cli_help(m['arg']).rstrip()}\n```"),
                            markdown)
    markdown = API.sub(lambda m: block("api", "", api_page()), markdown)
    markdown = CLAIMS.sub(lambda m: block("claims", m["arg"], claims_table(m["arg"])), markdown)
    markdown = MEANS.sub(lambda m: block("means", m["arg"], means_table(m["arg"])), markdown)
    return DOC.sub(lambda m: block("doc", m["arg"], doc_section(m["arg"])), markdown)


def claims_table(name: str) -> str:
    """A paper study's claims judged on its kept results (:data:`KEPT` / NAME), as ``fleet sweep report`` judges
    them (each at the look that decided it), in Markdown, with the command that shows the same."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from fleet_emu.sweep.decide import judged_as_decided
    from fleet_emu.sweep.intervals import Bootstrap, level_text
    from fleet_emu.sweep.report import load
    from fleet_emu.sweep.verdicts import markdown

    folder = KEPT / name
    rows, study, _ = load(folder)
    _, entries, level, _ = judged_as_decided(study, rows, study.get("study", {}).get("baseline"), folder, Bootstrap())
    runs = len(rows)
    looks = {e.get("replicates") for e in entries if e.get("replicates")}
    return (f"{markdown(entries)}\n{level_text(level)} intervals over replicates (n), {runs} runs"
            + (f"; replicates looked at: {', '.join(map(str, sorted(looks)))}" if looks else "")
            + f". `fleet sweep report docs/performance/claims/{name} --no-plots` prints the same from the kept "
            f"results.")


def means_table(name: str) -> str:
    """A paper study's kept results as a table of means: a line per setting the study varies (robot count, map,
    ...) by allocators (time to the target, mean ± std; with the robot count alone varied, also the % difference
    to the baseline's mean), else a line per allocator (time, moves, connected time, runs that reached the
    target); n is every cell's number of runs."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from fleet_emu.sweep.report import GROUP, axes, by, load, summary

    rows, study, _ = load(KEPT / name)
    head = study.get("study", {})
    base = head.get("baseline")
    lines = summary(rows, base, head.get("replicates", []))
    allocs = list(dict.fromkeys(str(ln["allocator"]) for ln in lines))
    counts = {ln["runs"] for ln in lines}
    split = [k for k in GROUP + axes(rows, head.get("replicates", [])) if len({str(ln[k]) for ln in lines}) > 1]

    def cell(ms: tuple[float, float, int]) -> str:
        return "-" if not ms[2] else f"{ms[0]:.1f} ± {ms[1]:.1f}"

    def pct(line: dict[str, Any]) -> str:
        shown = split == ["robots"] and str(line["allocator"]) != base
        return f" ({line['vs_baseline_pct']:+.1f} %)" if shown and line["vs_baseline_pct"] == line["vs_baseline_pct"] \
            else ""

    if split:
        out = ["| " + " | ".join(k.removeprefix("param.") for k in split) + " | " + " | ".join(allocs) + " |",
               "|" + " --- |" * (len(split) + len(allocs))]
        for key, group in by(lines, *split).items():
            of = {str(ln["allocator"]): ln for ln in group}
            cells = [cell(of[a]["ticks"]) + pct(of[a]) if a in of else "-" for a in allocs]
            out.append("| " + " | ".join(map(str, key)) + " | " + " | ".join(cells) + " |")
    else:
        out = ["| allocator | ticks to the target | moves | connected % | reached |", "| --- | --- | --- | --- | --- |"]
        out += [f"| {ln['allocator']} | {cell(ln['ticks'])} | {cell(ln['moves'])} | {cell(ln['connected_pct'])} | "
                f"{ln['reached']} / {ln['runs']} |" for ln in lines]
    n = f"n = {counts.pop()} runs per cell" if len(counts) == 1 else "n = " + ", ".join(map(str, sorted(counts)))
    return "\n".join(out) + f"\n\nMean ± std over each cell's runs that reached the target; {n}."


def keep(results: Path) -> Path:
    """Copy what the claims of a sweep's results read (``study.toml``, ``decided.json``, the rows' claim columns
    as Parquet) into :data:`KEPT` / the study's name."""
    import shutil
    import tomllib

    import pyarrow as pa
    import pyarrow.parquet as pq

    study = tomllib.loads((results / "study.toml").read_text())
    folder = KEPT / study["study"]["name"]
    folder.mkdir(parents=True, exist_ok=True)
    table = pq.read_table(results / "results.parquet")
    cols = [c for c in table.column_names if c.startswith("param.") or c in KEPT_COLUMNS]
    pq.write_table(pa.Table.from_pylist(table.select(cols).to_pylist()), folder / "results.parquet",
                   compression="zstd")
    shutil.copyfile(results / "study.toml", folder / "study.toml")
    if (results / "decided.json").is_file():
        shutil.copyfile(results / "decided.json", folder / "decided.json")
    return folder


def on_page_markdown(markdown: str, **_: Any) -> str:
    """MkDocs: the page with its generated parts current."""
    return refresh(markdown)


SCHEMA = ROOT / "recording" / "result.schema.json"


def compact_json(value: Any, indent: int = 0, width: int = 118) -> str:
    """JSON as the repository writes it: a value on one line when it fits in ``width``, else one member a line."""
    flat = json.dumps(value)
    if len(flat) + indent <= width or not isinstance(value, dict | list) or not value:
        return flat
    pad = " " * (indent + 2)
    if isinstance(value, dict):
        items = [f"{pad}{json.dumps(k)}: {compact_json(v, indent + 2, width)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + "\n" + " " * indent + "}"
    return "[\n" + ",\n".join(pad + compact_json(v, indent + 2, width) for v in value) + "\n" + " " * indent + "]"


def result_schema_text() -> str:
    """``result.schema.json`` with its ``$defs.scenario`` from the declared settings
    (:func:`fleet_emu.recording.result.scenario_schema`)."""
    from fleet_emu.recording.result import scenario_schema

    schema = json.loads(SCHEMA.read_text())
    schema["$defs"]["scenario"] = scenario_schema(schema["$defs"]["scenario_tables"])
    return compact_json(schema) + "\n"


def main() -> int:
    """``python docs/hooks.py``: rewrite the generated parts of :data:`PAGES` and of ``result.schema.json``; print
    the files that changed.
    ``python docs/hooks.py --keep RESULTS``: first keep a paper study's results for its claims table."""
    if sys.argv[1:2] == ["--keep"]:
        for results in sys.argv[2:]:
            print(f"kept {keep(Path(results)).relative_to(ROOT)}")
    for path, make in [*((ROOT / "docs" / page, refresh) for page in PAGES), (SCHEMA, lambda _: result_schema_text())]:
        text = path.read_text()
        new = make(text)
        if new != text:
            path.write_text(new)
            print(f"wrote {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
