"""Reading a scene file's YAML within bounds: every hostile input is a located SceneError, fast.

Bounds (a built-in scene is under 9 kB, under 1 000 nodes and 7 levels deep):

* the file is at most ``MAX_FILE_BYTES`` and UTF-8;
* at most ``MAX_NODES`` YAML nodes once aliases are expanded (an alias bomb — "billion laughs" —
  is refused before anything is built); an alias may not point into its own anchor;
* collections nest at most ``MAX_DEPTH`` deep (checked on the event stream, without recursion);
* no mapping repeats a key, and mapping keys are plain scalars (text or numbers).

Floats written with an exponent but no dot (``1e-3``) are numbers, as in YAML 1.2 (YAML 1.1, and
so PyYAML, reads them as text).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from chekhov.errors import SceneError

MAX_FILE_BYTES = 1 << 20  # 1 MiB
MAX_NODES = 50_000
MAX_DEPTH = 32

_Base: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_MERGE = "tag:yaml.org,2002:merge"


class _Loader(_Base):
    """SafeLoader (libyaml's when installed) that also reads 1e-3 as a float."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."))


def _line(mark: Any) -> str:
    return f" line {mark.line + 1}:" if mark is not None else ""


def _one_line(e: BaseException) -> str:
    """A YAML error as one line: what went wrong and, when known, where."""
    problem = getattr(e, "problem", None)
    mark = getattr(e, "problem_mark", None)
    if problem and mark is not None:
        return f"line {mark.line + 1}, column {mark.column + 1}: not valid YAML: {problem}"
    text = " ".join(str(e).replace('in "<unicode string>",', "at").split())
    return f"not valid YAML: {text}"


def _read_text(path: Path, source: str) -> str:
    """The file's text: refused when larger than MAX_FILE_BYTES (before reading) or not UTF-8."""
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise SceneError(f"{source}: file is {size / 2**20:.1f} MiB; a scene file may be at "
                             f"most {MAX_FILE_BYTES / 2**20:g} MiB")
        with open(path, "rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)
    except OSError as e:
        raise SceneError(f"{source}: cannot read scene file: {e.strerror}") from e
    if len(data) > MAX_FILE_BYTES:  # a device or a file that grew
        raise SceneError(f"{source}: more than {MAX_FILE_BYTES / 2**20:g} MiB; a scene file may "
                         f"be at most that")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise SceneError(f"{source}: line {line}: not UTF-8 text (byte 0x{data[e.start]:02x} at "
                         f"offset {e.start}); save the file as UTF-8") from e


def _check_events(loader: Any, source: str) -> None:
    """Depth, expanded node count and aliases, from the event stream (no recursion)."""
    sizes: dict[str, int] = {}  # anchor -> nodes once expanded
    stack: list[list[Any]] = []  # open collections: [anchor, nodes so far]
    total = 0
    while loader.check_event():
        ev = loader.get_event()
        if isinstance(ev, yaml.CollectionStartEvent):
            stack.append([ev.anchor, 1])
            if len(stack) > MAX_DEPTH:
                raise SceneError(f"{source}:{_line(ev.start_mark)} collections nested deeper "
                                 f"than {MAX_DEPTH} levels")
            n = 1
        elif isinstance(ev, yaml.CollectionEndEvent):
            anchor, n = stack.pop()
            if anchor is not None:
                sizes[anchor] = n
            if stack:
                stack[-1][1] += n
            continue
        elif isinstance(ev, yaml.AliasEvent):
            if ev.anchor not in sizes:
                what = ("recursive alias" if any(a == ev.anchor for a, _ in stack)
                        else "undefined alias")
                raise SceneError(f"{source}:{_line(ev.start_mark)} {what} *{ev.anchor}")
            n = sizes[ev.anchor]
        elif isinstance(ev, yaml.ScalarEvent):
            n = 1
            if ev.anchor is not None:
                sizes[ev.anchor] = 1
        else:
            continue
        total += n
        if total > MAX_NODES:
            raise SceneError(f"{source}:{_line(ev.start_mark)} more than {MAX_NODES} YAML nodes "
                             "once aliases are expanded (a scene needs far fewer)")
        if stack and not isinstance(ev, yaml.CollectionStartEvent):
            stack[-1][1] += n


def _check_keys(root: yaml.Node, source: str) -> None:
    """No mapping repeats a key; keys are scalars (walks each node once, without recursion)."""
    seen: set[int] = set()
    todo = [root]
    while todo:
        node = todo.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.SequenceNode):
            todo.extend(node.value)
        elif isinstance(node, yaml.MappingNode):
            first: dict[tuple[str, str], int] = {}
            for k, v in node.value:
                todo.append(v)
                if k.tag == _MERGE:
                    continue
                if not isinstance(k, yaml.ScalarNode):
                    raise SceneError(f"{source}:{_line(k.start_mark)} mapping keys must be text "
                                     f"or numbers, got a {k.id}")
                line = k.start_mark.line + 1
                if (k.tag, k.value) in first:
                    raise SceneError(f"{source}: line {line}: duplicate key {k.value[:80]!r} "
                                     f"(first at line {first[(k.tag, k.value)]})")
                first[(k.tag, k.value)] = line


def read_yaml(path: Path, source: str) -> Any:
    """The single YAML document in ``path``, within the bounds above; ``source`` names the file
    in error messages."""
    text = _read_text(path, source)
    loader = None
    try:
        loader = _Loader(text)  # the pure-Python reader checks the characters here
        _check_events(loader, source)
        loader.dispose()
        loader = _Loader(text)
        node = loader.get_single_node()
        if node is None:
            return None
        _check_keys(node, source)
        return loader.construct_document(node)
    except yaml.YAMLError as e:
        raise SceneError(f"{source}: {_one_line(e)}") from e
    except (ValueError, TypeError, OverflowError) as e:  # e.g. a date 2001-13-45, 5000 digits
        raise SceneError(f"{source}: not valid YAML: {' '.join(str(e).split())[:200]}") from e
    finally:
        if loader is not None:
            loader.dispose()
