"""Roadmap files: one versioned ``.npz`` (arrays + JSON metadata), written atomically.

Default location: ``$CHEKHOV_CACHE_DIR/roadmaps/SCENE.npz``; without that variable
``$XDG_CACHE_HOME/chekhov/roadmaps/SCENE.npz``, else ``~/.cache/chekhov/roadmaps/SCENE.npz``
(``SCENE@ROBOT.npz`` for a robot other than the scene's own).

Everything read is checked (:mod:`chekhov.roadmap.checks`): a missing, truncated, corrupt or
malformed file raises :class:`RoadmapError` naming the file and the field.
:func:`load_or_build_roadmap` rebuilds a cached file that cannot be used and says so.

A save writes ``.NAME.chekhov-HOST-PID-XXXXXXXX.tmp`` beside the target and renames it into
place; a process killed half-way leaves that temporary behind, and the next save or
:func:`load_or_build_roadmap` for the same target removes it once its writer is gone
(:func:`remove_stale_temporaries`).
"""

from __future__ import annotations

import glob
import json
import logging
import os
import re
import socket
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import numpy as np

from chekhov.atomic import write_atomic
from chekhov.roadmap.checks import check_arrays, check_meta, read_npz
from chekhov.roadmap.config import RoadmapConfig
from chekhov.roadmap.errors import RoadmapError, RoadmapMismatchError
from chekhov.roadmap.graph import Roadmap, RoadmapMeta, edges_certified
from chekhov.world import World

_ARRAYS = ("nodes", "node_kind", "node_label", "ee_position", "ee_rotation", "edges",
           "edge_length", "indptr", "indices", "weights", "edge_id", "dist", "pred",
           "kpath_key", "kpath_ptr", "kpath_nodes")
_MAGIC = "chekhov-roadmap"
_log = logging.getLogger(__name__)

# A temporary whose writer cannot be checked (another host, or a mkstemp name of an older
# chekhov) is stale when untouched this long, s; one whose writer's pid is alive (most likely a
# reused pid: a save writes continuously and takes seconds) after LIVE_STALE_S; one whose
# writer's pid is gone after DEAD_STALE_S (a margin for a writer in another pid namespace
# under the same host name, which keeps its file's mtime fresh while it writes).
STALE_S = 15 * 60.0
LIVE_STALE_S = 6 * 3600.0
DEAD_STALE_S = 30.0
_HOST = re.sub(r"[^A-Za-z0-9]", "", socket.gethostname())[:32]


def default_roadmap_dir() -> Path:
    """Folder of roadmap files built on demand (see the module docstring)."""
    if os.environ.get("CHEKHOV_CACHE_DIR"):
        return Path(os.environ["CHEKHOV_CACHE_DIR"]) / "roadmaps"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "chekhov" / "roadmaps"


def default_roadmap_path(scene_name: str, robot_name: str | None = None) -> Path:
    """``<scene>.npz`` in :func:`default_roadmap_dir` for the scene's own robot (``robot_name``
    None), ``<scene>@<robot>.npz`` for another one: arms tried in one scene each keep their
    roadmap, where they had taken turns overwriting one file (a UR10's took 11 minutes to
    build again after a Jaco's)."""
    if robot_name is None:
        return default_roadmap_dir() / f"{scene_name}.npz"
    return default_roadmap_dir() / f"{scene_name}@{re.sub(r'[^A-Za-z0-9_.-]', '_', robot_name)}.npz"


def world_roadmap_path(world: World) -> Path:
    """:func:`default_roadmap_path` of ``world``'s scene and robot."""
    own = world.robot.name == world.scene.robot
    return default_roadmap_path(world.scene.name, None if own else world.robot.name)


# --- writing -------------------------------------------------------------------------------
def save_roadmap(roadmap: Roadmap, path: str | Path) -> Path:
    """Write the roadmap to ``path`` atomically (temporary file renamed into place), so an
    interrupted write never leaves a corrupt file; stale temporaries of earlier, killed saves
    to ``path`` are removed first."""
    path = Path(path)
    m = roadmap.meta
    meta = {"magic": _MAGIC, "format_version": m.format_version, "robot": m.robot,
            "scene": m.scene, "scene_hash": m.scene_hash, "robot_hash": m.robot_hash,
            "config": m.config.to_dict(),
            "build_s": m.build_s, "created": m.created, "dropped_nodes": m.dropped_nodes,
            "node_counts": m.node_counts, "notes": m.notes}
    arrays = {k: getattr(roadmap, k) for k in _ARRAYS}
    arrays["meta_json"] = np.array(json.dumps(meta, default=_jsonable))
    _write_atomic(path, lambda f: np.savez(f, **arrays))
    return path


def _jsonable(x: Any) -> Any:
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


def temporary_name(path: Path, pid: int, token: str = "test") -> str:
    """The name of a temporary of a save to ``path`` by process ``pid`` on this host."""
    return f"{_tmp_prefix(path, pid)}{token}.tmp"


def _tmp_prefix(path: Path, pid: int) -> str:
    return f".{path.name}.chekhov-{_HOST}-{pid}-"


def _write_atomic(path: Path, write: Callable[[IO[bytes]], None]) -> None:
    """``write(file)`` into a temporary named by host and pid beside ``path``, then rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(path)
    write_atomic(path, write, "wb", prefix=_tmp_prefix(path, os.getpid()), suffix=".tmp")


def remove_stale_temporaries(path: str | Path, now: float | None = None) -> list[Path]:
    """Remove the temporaries that killed saves to ``path`` left beside it; returns them.

    Only this library's names for this target count: ``.NAME.chekhov-HOST-PID-*.tmp`` (removed
    when PID is gone on this host and the file is untouched for ``DEAD_STALE_S``, or untouched
    for ``LIVE_STALE_S``; from another host after ``STALE_S``) and the ``.NAME.XXXXXXXX`` of
    older versions (after ``STALE_S``). A temporary that a live process is writing is never
    removed. Errors (permissions …) are ignored.
    """
    path = Path(path)
    now = time.time() if now is None else now
    tagged = re.compile(rf"^\.{re.escape(path.name)}\.chekhov-(?P<host>[A-Za-z0-9]*)-"
                        r"(?P<pid>\d+)-[A-Za-z0-9_]+\.tmp$")
    legacy = re.compile(rf"^\.{re.escape(path.name)}\.[a-z0-9_]{{8}}$")
    removed = []
    for p in path.parent.glob(f".{glob.escape(path.name)}.*"):
        m = tagged.match(p.name)
        if m is None and legacy.match(p.name) is None:
            continue
        try:
            age = now - p.lstat().st_mtime
            if p.is_symlink() or not p.is_file():
                continue
            if m is not None and m["host"] == _HOST and int(m["pid"]) > 0:
                stale = age > LIVE_STALE_S or (age > DEAD_STALE_S
                                               and not _alive(int(m["pid"])))
            else:
                stale = age > STALE_S
            if stale:
                p.unlink()
                removed.append(p)
                _log.info("chekhov: removed %s, a temporary left by an interrupted save", p)
        except OSError:
            continue
    return removed


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this host (True when that cannot be told)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


# --- reading -------------------------------------------------------------------------------
def read_meta(path: str | Path) -> dict[str, Any]:
    """The checked JSON metadata of a roadmap file (cheap: does not read the arrays)."""
    path = Path(path)
    return check_meta(path, read_npz(path, ("meta_json",)).get("meta_json"), _MAGIC)


def check_compatible(meta: dict[str, Any], world: World, path: str | Path) -> None:
    """Raise :class:`RoadmapMismatchError` naming the file and every mismatch with world."""
    problems = []
    if meta["robot"] != world.robot.name:
        problems.append(f"robot '{meta['robot']}' (world: '{world.robot.name}')")
    else:
        rh = world.robot.content_hash()
        if meta.get("robot_hash", "") != rh:
            problems.append(f"robot '{meta['robot']}' with content hash "
                            f"{meta.get('robot_hash', '')[:12] or '(none recorded)'} (world: "
                            f"hash {rh[:12]}: its URDF, locked joints, spheres or base differ)")
    h = world.scene.content_hash()
    if meta["scene_hash"] != h:
        problems.append(f"scene '{meta['scene']}' with content hash {meta['scene_hash'][:12]} "
                        f"(world: scene '{world.scene.name}', hash {h[:12]})")
    if problems:
        raise RoadmapMismatchError(f"{path}: roadmap was built for another world: "
                                   + "; ".join(problems))


def load_roadmap(path: str | Path, world: World | None = None) -> Roadmap:
    """Read a roadmap file and check everything in it (metadata fields and types, array
    dtypes, shapes, finiteness, index ranges, CSR against edges); with ``world``, also check
    it was built for that world's robot (and its joint count) and scene (content hash).

    Raises :class:`RoadmapError` (:class:`RoadmapMismatchError` for another world or format
    version) naming the file and the field."""
    path = Path(path)
    data = read_npz(path, ("meta_json", *_ARRAYS))
    meta = check_meta(path, data.get("meta_json"), _MAGIC)
    if world is not None:
        check_compatible(meta, world, path)
    arrays = check_arrays(path, data, _ARRAYS, world.robot.dof if world is not None else None)
    rm_meta = RoadmapMeta(
        format_version=meta["format_version"], robot=meta["robot"], scene=meta["scene"],
        scene_hash=meta["scene_hash"], config=meta["config"], build_s=float(meta["build_s"]),
        created=meta["created"], dropped_nodes=meta["dropped_nodes"],
        node_counts=dict(meta["node_counts"]), notes=dict(meta["notes"]),
        robot_hash=meta.get("robot_hash", ""))
    return Roadmap(meta=rm_meta, **arrays)


def load_or_build_roadmap(world: World, config: RoadmapConfig | None = None,
                          path: str | Path | None = None,
                          progress: Callable[[str], None] | None = None) -> Roadmap:
    """The roadmap at ``path`` (default :func:`default_roadmap_path`) when it was built for
    this world with this config; otherwise build one and save it there.

    A file that cannot be used (truncated, corrupt, malformed, another world or config, or
    edges certified by another version of the check:
    :func:`~chekhov.roadmap.graph.edges_certified`) is rebuilt and overwritten; the reason
    goes to ``progress``, else (for an unreadable file) to the ``chekhov`` logger as a
    warning. A file of a newer format version is not
    overwritten: :class:`RoadmapMismatchError`. Stale temporaries of killed saves to ``path``
    are removed."""
    from chekhov.roadmap.build import build_roadmap

    config = config or RoadmapConfig()
    path = Path(path) if path is not None else world_roadmap_path(world)
    remove_stale_temporaries(path)
    if path.is_file():
        try:
            meta = read_meta(path)
            check_compatible(meta, world, path)
            certified_by = meta["notes"].get("edges_certified_by")
            if meta["config"] == config and (not config.certify_edges
                                             or edges_certified(config, meta["notes"])):
                return load_roadmap(path, world)
            reason = "built with another config" if meta["config"] != config else \
                f"its edges passed another certification ({certified_by or 'not recorded'})"
            level = logging.INFO
        except RoadmapMismatchError as e:
            if "format version" in str(e):
                raise
            reason, level = str(e), logging.INFO
        except RoadmapError as e:
            reason, level = str(e), logging.WARNING
        msg = f"rebuilding {path}: {reason}"
        if progress:
            progress(msg)
        else:
            _log.log(level, "chekhov: %s", msg)
    roadmap = build_roadmap(world, config, progress)
    save_roadmap(roadmap, path)
    return roadmap
