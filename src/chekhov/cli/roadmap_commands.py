"""Roadmap commands: ``chekhov roadmap build SCENE``, ``chekhov roadmap info FILE``."""

from __future__ import annotations

import argparse
import json
import sys

from chekhov.cli import checks

MAX_NODES = 20_000
"""Largest --nodes / --wrist-nodes: all-pairs distances (float32) grow as nodes², 1.6 GB at
20 000."""


def _cmd_build(args: argparse.Namespace) -> int:
    from chekhov.roadmap.build import build_roadmap
    from chekhov.roadmap.config import RoadmapConfig
    from chekhov.roadmap.io import default_roadmap_path, save_roadmap
    from chekhov.scene.io import load_scene
    from chekhov.world import World

    out = checks.output_file(args.out or default_roadmap_path(load_scene(args.scene).name),
                             "--out")
    world = World.load(args.scene)
    defaults = RoadmapConfig()
    config = RoadmapConfig(
        n_nodes=args.nodes, k_neighbors=args.k,
        max_neighbor_candidates=max(defaults.max_neighbor_candidates, args.k),
        semantic=not args.no_semantic, seed=args.seed,
        n_wrist_nodes=defaults.n_wrist_nodes if args.wrist_nodes is None else args.wrist_nodes)

    def say(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    roadmap = build_roadmap(world, config, progress=None if args.quiet else say)
    path = save_roadmap(roadmap, out)
    s = roadmap.summary()
    print(f"wrote {path}: {s['nodes']} nodes, {s['edges']} edges, {s['dropped_nodes']} dropped, "
          f"built in {s['build_s']} s, {roadmap.nbytes / 1e6:.1f} MB")
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    from chekhov.roadmap.io import load_roadmap

    checks.input_file(args.file, "roadmap file")
    roadmap = load_roadmap(args.file)
    s = roadmap.summary()
    if args.json:
        print(json.dumps(s))
        return 0
    for key, value in s.items():
        print(f"{key:16s} {value}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``chekhov roadmap build|info`` to the top-level parser."""
    p = sub.add_parser("roadmap", help="build or inspect a scene's roadmap")
    rsub = p.add_subparsers(dest="roadmap_command", required=True)
    b = rsub.add_parser("build", help="build a roadmap against a scene's static obstacles")
    b.add_argument("scene", help="built-in scene name or scene YAML file")
    b.add_argument("--out", default=None, metavar="FILE",
                   help="file to write (default: $CHEKHOV_CACHE_DIR or ~/.cache/chekhov, "
                        "roadmaps/SCENE.npz)")
    b.add_argument("--nodes", type=checks.int_at_least(2, MAX_NODES), default=1000, metavar="N",
                   help="uniform nodes (default 1000)")
    b.add_argument("--k", type=checks.int_at_least(1, 1000), default=10, metavar="K",
                   help="neighbours per node (default 10)")
    b.add_argument("--wrist-nodes", type=checks.int_at_least(0, MAX_NODES), default=None,
                   metavar="N",
                   help="extra nodes with random wrist joints (default 1000; 0: the paper's "
                        "scheme only)")
    b.add_argument("--no-semantic", action="store_true",
                   help="no pre-grasp or region nodes")
    b.add_argument("--seed", type=checks.SEED, default=0,
                   help=f"seed of the node sampling, 0..{checks.SEED_MAX} (default 0)")
    b.add_argument("--quiet", action="store_true", help="no progress output")
    b.set_defaults(func=_cmd_build)
    i = rsub.add_parser("info", help="describe a roadmap file")
    i.add_argument("file", metavar="FILE", help="roadmap file (.npz)")
    i.add_argument("--json", action="store_true", help="one JSON object")
    i.set_defaults(func=_cmd_info)
