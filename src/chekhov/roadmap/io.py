"""Roadmap files: one versioned ``.npz`` (arrays + JSON metadata), written atomically.

Default location: ``$CHEKHOV_CACHE_DIR/roadmaps/SCENE.npz``; without that variable
``$XDG_CACHE_HOME/chekhov/roadmaps/SCENE.npz``, else ``~/.cache/chekhov/roadmaps/SCENE.npz``.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from chekhov.roadmap.config import RoadmapConfig
from chekhov.roadmap.errors import RoadmapError, RoadmapMismatchError
from chekhov.roadmap.graph import FORMAT_VERSION, Roadmap, RoadmapMeta
from chekhov.scene.io import write_atomic
from chekhov.world import World

_ARRAYS = ("nodes", "node_kind", "node_label", "ee_position", "ee_rotation", "edges",
           "edge_length", "indptr", "indices", "weights", "edge_id", "dist", "pred",
           "kpath_key", "kpath_ptr", "kpath_nodes")
_MAGIC = "chekhov-roadmap"


def default_roadmap_dir() -> Path:
    """Folder of roadmap files built on demand (see the module docstring)."""
    if os.environ.get("CHEKHOV_CACHE_DIR"):
        return Path(os.environ["CHEKHOV_CACHE_DIR"]) / "roadmaps"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "chekhov" / "roadmaps"


def default_roadmap_path(scene_name: str) -> Path:
    return default_roadmap_dir() / f"{scene_name}.npz"


def save_roadmap(roadmap: Roadmap, path: str | Path) -> Path:
    """Write the roadmap to ``path`` atomically (temporary file renamed into place), so an
    interrupted write never leaves a corrupt file."""
    path = Path(path)
    m = roadmap.meta
    meta = {"magic": _MAGIC, "format_version": m.format_version, "robot": m.robot,
            "scene": m.scene, "scene_hash": m.scene_hash, "config": m.config.to_dict(),
            "build_s": m.build_s, "created": m.created, "dropped_nodes": m.dropped_nodes,
            "node_counts": m.node_counts, "notes": m.notes}
    arrays = {k: getattr(roadmap, k) for k in _ARRAYS}
    arrays["meta_json"] = np.array(json.dumps(meta, default=_jsonable))
    write_atomic(path, lambda f: np.savez(f, **arrays), mode="wb")
    return path


def _jsonable(x: Any) -> Any:
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


def read_meta(path: str | Path) -> dict[str, Any]:
    """The JSON metadata of a roadmap file (cheap: does not read the arrays)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            if "meta_json" not in z.files:
                raise RoadmapError(f"{path}: not a chekhov roadmap file (no metadata)")
            meta = json.loads(str(z["meta_json"]))
    except (OSError, ValueError, zipfile.BadZipFile, json.JSONDecodeError) as e:
        raise RoadmapError(f"{path}: cannot read roadmap file: {e}") from e
    if not isinstance(meta, dict) or meta.get("magic") != _MAGIC:
        raise RoadmapError(f"{path}: not a chekhov roadmap file")
    version = meta.get("format_version")
    if not isinstance(version, int) or version > FORMAT_VERSION or version < 1:
        raise RoadmapMismatchError(
            f"{path}: roadmap format version {version!r} is not supported by this chekhov "
            f"(reads versions 1..{FORMAT_VERSION}); rebuild it with `chekhov roadmap build`")
    return meta


def check_compatible(meta: dict[str, Any], world: World, path: str | Path) -> None:
    """Raise :class:`RoadmapMismatchError` naming the file and every mismatch with world."""
    problems = []
    if meta["robot"] != world.robot.name:
        problems.append(f"robot '{meta['robot']}' (world: '{world.robot.name}')")
    h = world.scene.content_hash()
    if meta["scene_hash"] != h:
        problems.append(f"scene '{meta['scene']}' with content hash {meta['scene_hash'][:12]} "
                        f"(world: scene '{world.scene.name}', hash {h[:12]})")
    if problems:
        raise RoadmapMismatchError(f"{path}: roadmap was built for another world: "
                                   + "; ".join(problems))


def load_roadmap(path: str | Path, world: World | None = None) -> Roadmap:
    """Read a roadmap file; with ``world``, also check it was built for that world's robot and
    scene (content hash)."""
    path = Path(path)
    meta = read_meta(path)
    if world is not None:
        check_compatible(meta, world, path)
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in _ARRAYS}
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as e:
        raise RoadmapError(f"{path}: cannot read roadmap arrays: {e}") from e
    rm_meta = RoadmapMeta(
        format_version=int(meta["format_version"]), robot=meta["robot"], scene=meta["scene"],
        scene_hash=meta["scene_hash"], config=RoadmapConfig.from_dict(meta["config"]),
        build_s=float(meta["build_s"]), created=meta["created"],
        dropped_nodes=int(meta["dropped_nodes"]), node_counts=dict(meta["node_counts"]),
        notes=dict(meta["notes"]))
    return Roadmap(meta=rm_meta, **arrays)


def load_or_build_roadmap(world: World, config: RoadmapConfig | None = None,
                          path: str | Path | None = None,
                          progress: Callable[[str], None] | None = None) -> Roadmap:
    """The roadmap at ``path`` (default :func:`default_roadmap_path`) when it was built for
    this world with this config; otherwise build one and save it there."""
    from chekhov.roadmap.build import build_roadmap

    config = config or RoadmapConfig()
    path = Path(path) if path is not None else default_roadmap_path(world.scene.name)
    if path.is_file():
        try:
            meta = read_meta(path)
            check_compatible(meta, world, path)
            if RoadmapConfig.from_dict(meta["config"]) == config:
                return load_roadmap(path, world)
            reason = "built with another config"
        except RoadmapMismatchError as e:
            if "format version" in str(e):
                raise
            reason = str(e)
        except RoadmapError as e:
            reason = str(e)
        if progress:
            progress(f"rebuilding {path}: {reason}")
    roadmap = build_roadmap(world, config, progress)
    save_roadmap(roadmap, path)
    return roadmap
