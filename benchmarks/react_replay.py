"""Replay chosen ``chekhov react`` episodes on fixed scripts, to compare two versions of the
executive on the same disturbances. One JSON object per episode and repetition.

    python benchmarks/react_replay.py SCENE EPISODE [EPISODE ...] [--scripts FILE] [--reps N]
        [--search-budget-ms MS|none] [--compute-scale X]

An episode's script (kick, goal change, forearm) is timed by an undisturbed run of the
planner; until 2026-12-01 that run charged its compute, whose wall time moved replies from
tick to tick, so two ``chekhov react`` runs could differ by a few ms in every script (the same
seed); now it runs on the free clock, and the scripts are those of ``chekhov react``. Here
the scripts are made once and kept in
``--scripts`` (a pickle: load only files you made; written atomically), then replayed with
whatever ``chekhov`` is imported — e.g. ``PYTHONPATH=/path/to/other/checkout/src``.

``--search-budget-ms`` sets the executive's ``search_budget_s`` (``none``: no budget); the
default is :class:`ExecutorConfig`'s. ``--compute-scale`` is ``chekhov react``'s (the executive's
compute charged to the simulated clock × X: a slower machine); the scripts do not depend on it.

Keys: scene, episode, rep, search_budget_ms, reached, t_reached_s, collision, first_contact_s,
unavoidable, limit_violations, dodges, safe_stops, holds, replans, failures (plan failures by
status), step_ms_max (the control step's own compute).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: idle BLAS threads would only spin

import argparse
import json
import pickle
from collections import Counter
from dataclasses import replace
from pathlib import Path

from chekhov import World
from chekhov.atomic import write_atomic
from chekhov.errors import ChekhovError
from chekhov.execute.benchmark import ReactConfig, executive_planner, run_one
from chekhov.execute.interface import ExecutorConfig
from chekhov.execute.script import EpisodeScript, make_script, start_and_goal
from chekhov.execute.simulate import SimConfig

try:
    from chekhov.execute.benchmark import scripted_episode
except ImportError:      # a checkout from before 2026-11-26, to compare against
    from chekhov.execute.benchmark import _episode as scripted_episode  # type: ignore
try:
    from chekhov.execute.benchmark import episode_script
except ImportError:      # a checkout from before 2026-12-01 (its scripts from a charged run)
    episode_script = None  # type: ignore[assignment]


def scripts_for(world: World, episodes: list[int], config: ReactConfig,
                path: Path | None) -> dict[int, tuple[EpisodeScript, float | None]]:
    """Each episode's script and undisturbed duration (s; None: the replay runs the task
    alone for it): read from ``path`` when it holds them, else made (and written there) —
    since 2026-12-01 as ``chekhov react`` makes them, on the clock that does not charge
    compute, so a run's collided episode replays on its own script."""
    kept: dict[int, tuple[EpisodeScript, float | None]] = {}
    if path is not None and path.exists():
        try:
            kept = pickle.loads(path.read_bytes())
        except (OSError, EOFError, pickle.UnpicklingError, AttributeError) as e:
            raise SystemExit(f"react_replay: --scripts {path}: not a scripts file of this "
                             f"tool ({e})") from e
    planner = executive_planner(config.planners[0], world)
    for i in episodes:
        if i in kept:
            continue
        if episode_script is not None:    # the same script as chekhov react's (free clock)
            script = episode_script(world, planner, config, i)
            if script is None:
                raise SystemExit(f"episode {i}: the undisturbed run does not reach its goal")
            kept[i] = (script, None)
            continue
        q0, goal = start_and_goal(world, config.seed, i)
        rec = run_one(world, planner, EpisodeScript(i, q0, goal, ""), config.undisturbed_limit_s,
                      config)
        if rec.t_reached is None:
            raise SystemExit(f"episode {i}: the undisturbed run does not reach its goal")
        ee = world.robot.compute_ee_poses(rec.q)[:, :3, 3]
        kept[i] = (make_script(world, config.seed, i, rec.t_reached, ee, rec.q), rec.t_reached)
    if path is not None:
        write_atomic(path, lambda f: pickle.dump(kept, f), mode="wb")
    return kept


def _budget_s(text: str) -> float | None:
    """``--search-budget-ms``: a positive number of ms (returned in s), or ``none``."""
    if text.lower() == "none":
        return None
    try:
        ms = float(text)
    except ValueError:
        ms = -1.0
    if not ms > 0:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a positive number of ms or 'none'")
    return ms / 1000


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("episodes", type=int, nargs="+")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--scripts", type=Path, default=None)
    ap.add_argument("--reps", type=int, default=1)
    ap.add_argument("--search-budget-ms", type=_budget_s, dest="search_budget_s",
                    default=ExecutorConfig().search_budget_s)
    ap.add_argument("--compute-scale", type=float, default=SimConfig().compute_scale)
    args = ap.parse_args()
    try:
        world = World.load(args.scene)
    except ChekhovError as e:
        raise SystemExit(f"react_replay: scene {args.scene!r}: {e}") from e
    config = ReactConfig(episodes=max(args.episodes) + 1, seed=args.seed)
    config = replace(config, executor=replace(config.executor,
                                              search_budget_s=args.search_budget_s),
                     sim=replace(config.sim, compute_scale=args.compute_scale))
    budget = config.executor.search_budget_s
    scripts = scripts_for(world, args.episodes, config, args.scripts)
    planner = executive_planner(config.planners[0], world)
    for i in args.episodes:
        script, t_plain = scripts[i]
        for rep in range(args.reps):
            r = scripted_episode(world, planner, script, config, t_plain)
            rec, check, c = r.record, r.check, r.record.counters
            print(json.dumps({
                "scene": args.scene, "episode": i, "rep": rep,
                "search_budget_ms": None if budget is None else 1000 * budget,
                "reached": rec.reached,
                "t_reached_s": rec.t_reached, "collision": check.collision,
                "first_contact_s": check.first_contact_s, "unavoidable": check.unavoidable,
                "limit_violations": check.limit_violations, "dodges": c.dodges,
                "safe_stops": c.safe_stops, "holds": c.holds, "replans": c.replans,
                "failures": dict(Counter(c.failures)),
                "step_ms_max": round(1000 * max(c.step_wall_s), 1) if c.step_wall_s else None,
            }), flush=True)


if __name__ == "__main__":
    main()
