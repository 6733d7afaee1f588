"""The ``chekhov`` command line. One module per command group; each has ``register(sub)``.

    chekhov scenes                         list the built-in scenes
    chekhov show SCENE [--q Q...] [--out scene.png]
                                           picture of a scene with the robot at q
    chekhov demo [--out DIR]               the main job (see README)
"""

from __future__ import annotations

import argparse
import sys

from chekhov.cli import (
    bench_commands,
    cases_commands,
    roadmap_commands,
    scene_commands,
    view_commands,
)
from chekhov.errors import ChekhovError

COMMAND_GROUPS = [scene_commands, cases_commands, roadmap_commands, view_commands,
                  bench_commands]


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="chekhov", description="Fast, reactive motion planning.")
    sub = ap.add_subparsers(dest="command", required=True)
    for group in COMMAND_GROUPS:
        group.register(sub)
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except ChekhovError as e:
        print(f"chekhov: error: {e}", file=sys.stderr)
        return 2
