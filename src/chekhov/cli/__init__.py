"""The ``chekhov`` command line. One module per command group; each has ``register(sub)``.

    chekhov scenes                         list the built-in scenes
    chekhov show SCENE [--q Q...] [--out scene.png]
                                           picture of a scene with the robot at q
    chekhov demo [--out DIR]               the main job (see README)
    chekhov react [--scenes ...] [--json]  the reactive executive's scenario benchmark

Exit status: 0 done, 2 bad arguments or input files (argparse's usage errors too), 1 the
system refused (an OSError: disk full, permissions …), 130 interrupted (Ctrl-C), 141 the
reader of stdout went away (``chekhov scenes | head -1``).
Every failure is one line on stderr, never a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys

from chekhov.cli import (
    bench_commands,
    cases_commands,
    react_commands,
    roadmap_commands,
    scene_commands,
    view_commands,
)
from chekhov.errors import ChekhovError

COMMAND_GROUPS = [scene_commands, cases_commands, roadmap_commands, view_commands,
                  bench_commands, react_commands]


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="chekhov", description="Fast, reactive motion planning.")
    sub = ap.add_subparsers(dest="command", required=True)
    for group in COMMAND_GROUPS:
        group.register(sub)
    return ap


def _fail(message: str, code: int) -> int:
    """Print ``message`` as one line on stderr; returns ``code``."""
    line = "; ".join(part.strip() for part in message.splitlines() if part.strip())
    print(f"chekhov: error: {line}", file=sys.stderr)
    return code


def _os_message(e: OSError) -> str:
    where = f"{e.filename}: " if e.filename else ""
    also = f" -> {e.filename2}" if e.filename2 else ""
    return f"{where}{e.strerror or e}{also}"


def _quiet_stdout() -> None:
    """After a broken pipe (``chekhov scenes | head -1``): send what is left to /dev/null, so
    the interpreter's final flush does not complain."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def main(argv: list[str] | None = None) -> int:
    """Run one command; returns the exit status (see the module docstring)."""
    args = build_parser().parse_args(argv)
    try:
        code = int(args.func(args))
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's final flush
        return code
    except ChekhovError as e:
        return _fail(str(e), 2)
    except KeyboardInterrupt:
        print("chekhov: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        _quiet_stdout()
        return 141
    except OSError as e:
        return _fail(_os_message(e), 1)
    except MemoryError:
        return _fail("out of memory (ask for fewer cases, nodes or workers)", 1)
