"""The command line every child process takes: ``--run``, ``--connect``, ``--scenario FILE.json``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from core.scenario import ConfigError, Scenario


def parse_child(parser: argparse.ArgumentParser, argv: list[str] | None) -> argparse.Namespace:
    parser.add_argument("--run", required=True, help="run id (the <run> of the key expressions)")
    parser.add_argument("--connect", required=True, help="router endpoint, e.g. tcp/127.0.0.1:7447")
    parser.add_argument("--scenario", required=True, type=Path, help="scenario as JSON (written by fleet run)")
    args = parser.parse_args(argv)
    try:
        args.scenario = Scenario.from_dict(json.loads(args.scenario.read_text())).validate()
    except (OSError, ValueError, TypeError, ConfigError) as exc:
        print(f"{parser.prog}: error: bad scenario {args.scenario}: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    return args
