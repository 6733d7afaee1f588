"""Checks of what a roadmap file holds, before any of it reaches scipy, numba or pinocchio.

Every failure is a :class:`RoadmapError` (:class:`RoadmapMismatchError` for a format version
this code does not read) naming the file and the field, e.g.
``rm.npz: array 'edges' holds node index 212, outside [0, 75)``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np

from chekhov.npzfile import read_npz as _read_npz
from chekhov.roadmap.config import RoadmapConfig
from chekhov.roadmap.errors import RoadmapError, RoadmapMismatchError
from chekhov.roadmap.graph import FORMAT_VERSION, NODE_KINDS

_KINDS = {"f": "floating point", "iu": "integer", "U": "unicode strings"}


def _int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


# meta field: (check, what the message says is expected)
_META: dict[str, tuple[Any, str]] = {
    "robot": (lambda v: isinstance(v, str), "a string"),
    "scene": (lambda v: isinstance(v, str), "a string"),
    "scene_hash": (lambda v: isinstance(v, str), "a string"),
    "created": (lambda v: isinstance(v, str), "a string (ISO 8601 time)"),
    "config": (lambda v: isinstance(v, dict), "an object (the RoadmapConfig)"),
    "build_s": (lambda v: _number(v) and v >= 0, "a number of seconds ≥ 0"),
    "dropped_nodes": (lambda v: _int(v) and v >= 0, "an integer ≥ 0"),
    "node_counts": (lambda v: isinstance(v, dict) and all(
        isinstance(k, str) and _int(n) and n >= 0 for k, n in v.items()),
        "an object of node kind: count ≥ 0"),
    "notes": (lambda v: isinstance(v, dict), "an object"),
}


def read_npz(path: Path, keys: Iterable[str]) -> dict[str, np.ndarray]:
    """The arrays ``keys`` (those present) of the roadmap file at ``path``; RoadmapError
    when it is missing, not an archive, truncated or corrupt."""
    return _read_npz(path, keys, RoadmapError, "roadmap")


def check_meta(path: Path, m: np.ndarray | None, magic: str) -> dict[str, Any]:
    """The checked JSON header (``meta_json``), with ``config`` as a :class:`RoadmapConfig`."""
    if m is None or m.shape != () or m.dtype.kind != "U":
        raise RoadmapError(f"{path}: not a chekhov roadmap file (no 'meta_json' metadata)")
    try:
        meta = json.loads(str(m))
    except (ValueError, RecursionError) as e:
        raise RoadmapError(f"{path}: roadmap metadata 'meta_json' is not JSON ({e})") from e
    if not isinstance(meta, dict) or meta.get("magic") != magic:
        raise RoadmapError(f"{path}: not a chekhov roadmap file (its 'meta_json' metadata is "
                           f"not an object with magic '{magic}')")
    version: Any = meta.get("format_version")
    if not (_int(version) and 1 <= version <= FORMAT_VERSION):
        raise RoadmapMismatchError(
            f"{path}: roadmap format version {version!r:.20} is not supported by this chekhov "
            f"(reads versions 1..{FORMAT_VERSION}); rebuild it with `chekhov roadmap build`")
    for key, (ok, expected) in _META.items():
        if key not in meta:
            raise RoadmapError(f"{path}: roadmap metadata lacks the field '{key}'")
        if not ok(meta[key]):
            raise RoadmapError(f"{path}: roadmap metadata field '{key}' must be {expected}, "
                               f"got {meta[key]!r:.60}")
    if not isinstance(meta.get("robot_hash", ""), str):   # optional: absent in older files
        raise RoadmapError(f"{path}: roadmap metadata field 'robot_hash' must be a string, "
                           f"got {meta['robot_hash']!r:.60}")
    return {**meta, "config": _config(path, meta["config"])}


def _config(path: Path, d: dict[str, Any]) -> RoadmapConfig:
    """The RoadmapConfig of the metadata, each field's type checked."""
    defaults = {f.name: f.default for f in fields(RoadmapConfig)}
    unknown = sorted(set(d) - set(defaults))
    if unknown:
        raise RoadmapError(f"{path}: roadmap metadata field 'config' has unknown field(s) "
                           f"{unknown}")
    for k, v in d.items():
        default = defaults[k]
        if k == "distal_values":
            ok, expected = v is None or (isinstance(v, list) and all(map(_number, v))), \
                "null or a list of finite numbers (rad)"
        elif k == "proximal_joints":
            ok, expected = v is None or _int(v), "null or an integer"
        elif isinstance(default, bool):
            ok, expected = isinstance(v, bool), "true or false"
        elif isinstance(default, int):
            ok, expected = _int(v), "an integer"
        elif isinstance(default, float):
            ok, expected = _number(v), "a finite number"
        else:
            ok, expected = True, ""
        if not ok:
            raise RoadmapError(f"{path}: roadmap metadata field 'config.{k}' must be "
                               f"{expected}, got {v!r:.40}")
    try:
        return RoadmapConfig.from_dict(d)
    except (RoadmapError, TypeError, ValueError) as e:
        raise RoadmapError(f"{path}: roadmap metadata field 'config': {e}") from e


class _Arrays:
    """The arrays of one file, each checked when taken (dtype kind, shape)."""

    def __init__(self, path: Path, data: dict[str, np.ndarray]) -> None:
        self.path, self.data = path, data

    def fail(self, name: str, what: str) -> RoadmapError:
        return RoadmapError(f"{self.path}: array '{name}' {what}")

    def get(self, name: str, kind: str, shape: tuple[int | None, ...]) -> np.ndarray:
        x = self.data[name]
        if x.dtype.kind not in kind:
            raise self.fail(name, f"has dtype {x.dtype}, expected {_KINDS[kind]}")
        if x.ndim != len(shape) or any(s is not None and s != d
                                       for s, d in zip(shape, x.shape, strict=True)):
            want = "(" + ", ".join("any" if s is None else str(s) for s in shape) + ")"
            raise self.fail(name, f"has shape {x.shape}, expected {want}")
        return x

    def floats(self, name: str, shape: tuple[int | None, ...], nonneg: bool = False,
               inf: bool = False) -> np.ndarray:
        """A float array without NaN (nor inf unless ``inf``), ≥ 0 when ``nonneg``."""
        x = self.get(name, "f", shape)
        if np.isnan(x).any() or (not inf and np.isinf(x).any()):
            raise self.fail(name, "holds NaN or infinite values")
        if nonneg and x.size and x.min() < 0:
            raise self.fail(name, f"holds negative values ({x.min()})")
        return x

    def indices(self, name: str, shape: tuple[int | None, ...], hi: int,
                what: str = "node index") -> np.ndarray:
        """An integer array with values in [0, hi)."""
        x = self.get(name, "iu", shape)
        if x.size and (x.min() < 0 or x.max() >= hi):
            bad = x.min() if x.min() < 0 else x.max()
            raise self.fail(name, f"holds {what} {bad}, outside [0, {hi})")
        return x

    def offsets(self, name: str, n: int, total: int) -> np.ndarray:
        """CSR-style offsets: n + 1 integers from 0, non-decreasing, ending at total."""
        x = self.get(name, "iu", (n + 1,))
        if x[0] != 0 or x[-1] != total or (np.diff(x) < 0).any():
            raise self.fail(name, f"must rise from 0 to {total}, got {x[0]} .. {x[-1]}"
                            + (" (decreasing)" if (np.diff(x) < 0).any() else ""))
        return x


def check_arrays(path: Path, data: dict[str, np.ndarray], names: Iterable[str],
                 dof: int | None = None) -> dict[str, np.ndarray]:
    """Every roadmap array checked (see :class:`chekhov.roadmap.graph.Roadmap` for the
    layout) and cast to the dtype the planners use; ``dof``: the robot's joint count."""
    names = tuple(names)
    for k in names:
        if k not in data:
            raise RoadmapError(f"{path}: roadmap file lacks the array '{k}'")
    a = _Arrays(path, data)
    nodes = a.floats("nodes", (None, None))
    N, K = nodes.shape
    if N < 1 or K < 1:
        raise a.fail("nodes", f"has shape {nodes.shape}: no nodes or no joints")
    if dof is not None and dof != K:
        raise a.fail("nodes", f"has {K} joints per node, the robot has {dof}")
    a.indices("node_kind", (N,), len(NODE_KINDS), "node kind")
    a.get("node_label", "U", (N,))
    a.floats("ee_position", (N, 3))
    a.floats("ee_rotation", (N, 3, 3))
    edges = a.indices("edges", (None, 2), N)
    E = len(edges)
    if E and not (edges[:, 0] < edges[:, 1]).all():
        raise a.fail("edges", "holds a pair (i, j) without i < j")
    edge_length = a.floats("edge_length", (E,), nonneg=True)
    _check_csr(a, N, edges, edge_length)
    a.floats("dist", (N, N), nonneg=True, inf=True)
    pred = a.get("pred", "iu", (N, N))
    if not ((pred == -9999) | ((pred >= 0) & (pred < N))).all():
        raise a.fail("pred", f"holds predecessors outside [0, {N}) and not -9999 (none)")
    key = a.get("kpath_key", "iu", (None, 3))
    if key.size and (key[:, :2].min() < 0 or key[:, :2].max() >= N or key[:, 2].min() < 0):
        raise a.fail("kpath_key", f"holds a (src, dst, rank) row with a node outside [0, {N}) "
                     "or a negative rank")
    kpath_nodes = a.indices("kpath_nodes", (None,), N)
    a.offsets("kpath_ptr", len(key), len(kpath_nodes))
    dtypes = {"nodes": np.float64, "node_kind": np.int8, "ee_position": np.float64,
              "ee_rotation": np.float64, "edges": np.int32, "edge_length": np.float64,
              "indptr": np.int64, "indices": np.int64, "weights": np.float64,
              "edge_id": np.int64, "dist": np.float32,
              "pred": np.int16 if N < 32767 else np.int32, "kpath_key": np.int32,
              "kpath_ptr": np.int64, "kpath_nodes": np.int32}
    return {k: data[k].astype(dtypes[k], copy=False) if k in dtypes else data[k]
            for k in names}


def _check_csr(a: _Arrays, N: int, edges: np.ndarray, edge_length: np.ndarray) -> None:
    """The CSR adjacency (both directions of every edge) agrees with ``edges``."""
    E = len(edges)
    indptr = a.offsets("indptr", N, 2 * E)
    indices = a.indices("indices", (2 * E,), N)
    weights = a.floats("weights", (2 * E,), nonneg=True)
    edge_id = a.indices("edge_id", (2 * E,), E, "edge index")
    if E == 0:
        return
    rows = np.repeat(np.arange(N), np.diff(indptr))
    e = edges[edge_id]
    ok = (((rows == e[:, 0]) & (indices == e[:, 1])) | ((rows == e[:, 1]) & (indices == e[:, 0]))
          ) & (weights == edge_length[edge_id])
    if not ok.all():
        raise a.fail("indices", f"(with 'indptr', 'weights', 'edge_id') disagrees with 'edges' "
                     f"and 'edge_length' at entry {int(np.argmin(ok))}")
