"""PNG plots of a benchmark database (matplotlib, Agg backend), written atomically.

* ``runtime_distribution.png``: per scene and case family, a box plot of every planner's
  runtimes (log scale).
* ``failure_rate.png``, ``path_length.png``: per scene and case family, bars per planner.
* ``figure3.png``: like the paper's Figure 3, the four proximal joints along three
  Roadmap+TrajOpt plans: the roadmap seed solid, the optimised trajectory dashed, against the
  normalised joint-space arc length.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

from chekhov.bench.files import write_file
from chekhov.bench.summary import ROADMAP, Stats, StatsKey, stats_label


def _plt() -> Any:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig: Any, path: Path) -> Path:
    def write(f: IO[bytes]) -> None:
        fig.savefig(f, format="png", dpi=110, bbox_inches="tight")

    write_file(path, write, mode="wb")
    _plt().close(fig)
    return path


def _label(key: StatsKey, stats: Stats) -> str:
    return stats_label(key, stats)


def planner_order(names: Sequence[str]) -> list[str]:
    """Roadmap+TrajOpt first, then each planner followed by its +TrajOpt."""
    def key(n: str) -> tuple[int, str, int]:
        base = n.removesuffix("+TrajOpt")
        return (0 if n == ROADMAP else 1, base, int(n.endswith("+TrajOpt")))
    return sorted(names, key=key)


def runtime_distribution(rows: list[dict[str, Any]], stats: Stats, path: Path) -> Path:
    """Box plots of runtimes (s, log scale) per planner, one panel per scene."""
    plt = _plt()
    keys = sorted(stats)
    fig, axes = plt.subplots(len(keys), 1, figsize=(9, 2.2 + 0.35 * _max_planners(stats)
                                                    * len(keys)), squeeze=False)
    for ax, key in zip(axes[:, 0], keys, strict=True):
        scene, limit, family = key
        names = planner_order(list(stats[key]))
        data = [[max(r["time"], 1e-4) for r in rows if r["scene"] == scene
                 and float(r["timelimit"]) == limit
                 and (r.get("family") or "random") == family and r["planner"] == n]
                for n in names]
        style: dict[str, Any] = {"whis": (5, 95), "showfliers": True, "flierprops": {"ms": 2}}
        try:
            ax.boxplot(data, orientation="horizontal", **style)   # matplotlib >= 3.10
        except TypeError:
            ax.boxplot(data, vert=False, **style)
        ax.set_yticks(range(1, len(names) + 1), names)
        ax.set_xscale("log")
        ax.axvline(limit, color="grey", ls=":", lw=1)
        ax.set_title(f"{_label(key, stats)}: planning time per run "
                     f"(whiskers 5–95%, dotted: limit {limit:g} s)", fontsize=9)
        ax.set_xlabel("runtime (s, log scale)")
        ax.invert_yaxis()
    fig.tight_layout()
    return _save(fig, path)


def _max_planners(stats: Stats) -> int:
    return max((len(v) for v in stats.values()), default=1)


def _bars(stats: Stats, path: Path, value: str, ylabel: str, title: str,
          percent: bool = False) -> Path:
    plt = _plt()
    keys = sorted(stats)
    names = planner_order(sorted({n for v in stats.values() for n in v}))
    fig, ax = plt.subplots(figsize=(max(6.0, 1.6 * len(keys) + 0.3 * len(names)), 4))
    width = 0.8 / max(len(names), 1)
    x = np.arange(len(keys))
    cmap = plt.get_cmap("tab20")
    for j, n in enumerate(names):
        vals = []
        for k in keys:
            s = stats[k].get(n)
            v = getattr(s, value) if s is not None else math.nan
            vals.append(100 * v if percent and math.isfinite(v) else v)
        ax.bar(x + (j - (len(names) - 1) / 2) * width, vals, width, label=n, color=cmap(j))
    ax.set_xticks(x, [_label(k, stats) for k in keys])
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7, ncol=2, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    fig.tight_layout()
    return _save(fig, path)


def failure_rate(stats: Stats, path: Path) -> Path:
    return _bars(stats, path, "failure_rate", "failure rate (%)",
                 "Failure rate per scene (no path, or a path the exact check rejects)",
                 percent=True)


def path_length(stats: Stats, path: Path) -> Path:
    return _bars(stats, path, "mean_path_length_rad", "mean joint-space path length (rad)",
                 "Mean path length per scene (successful runs)")


def figure3(rows: list[dict[str, Any]], path: Path, n_cases: int = 3, joints: int = 4,
            prefer_scene: str = "tabletop_pole") -> Path | None:
    """The paper's Figure 3 from Roadmap+TrajOpt runs with a stored roadmap seed and an
    optimised (not fallback) path; None when there are none. ``rows`` need paths."""
    cand = [r for r in rows if r["planner"] == ROADMAP and r["success"]
            and not r["fallback_to_seed"] and r.get("seed_path") is not None
            and r.get("path") is not None]
    if not cand:
        return None
    scenes = [r["scene"] for r in cand]
    scene = prefer_scene if prefer_scene in scenes else scenes[0]
    picked = sorted((r for r in cand if r["scene"] == scene), key=lambda r: r["case_index"])
    picked = picked[:n_cases]
    plt = _plt()
    fig, axes = plt.subplots(1, len(picked), figsize=(4.2 * len(picked), 3.4), squeeze=False)
    colors = plt.get_cmap("tab10")
    for ax, r in zip(axes[0], picked, strict=True):
        for name, P, ls in (("roadmap seed", r["seed_path"], "-"),
                            ("TrajOpt", r["path"], "--")):
            s = _arc(P)
            for j in range(min(joints, P.shape[1])):
                ax.plot(s, P[:, j], ls=ls, color=colors(j), lw=1.4,
                        label=f"joint {j + 1} {name}")
        ax.set_title(f"{scene}, case {r['case_index']}: seed {_arc_len(r['seed_path']):.2f} "
                     f"rad → {_arc_len(r['path']):.2f} rad", fontsize=9)
        ax.set_xlabel("normalised path length")
        ax.set_ylabel("joint angle (rad)")
    axes[0, -1].legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    fig.suptitle("Four proximal joints: roadmap seeds (solid) and TrajOpt's trajectories "
                 "(dashed)", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def _arc(P: np.ndarray) -> np.ndarray:
    d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    return d / d[-1] if d[-1] > 0 else np.linspace(0.0, 1.0, len(P))


def _arc_len(P: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())
