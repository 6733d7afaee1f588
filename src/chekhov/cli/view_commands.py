"""Viewer command: ``chekhov view SCENE`` starts the interactive 3D viewer in the browser;
``--react`` shows the reactive executive live instead."""

from __future__ import annotations

import argparse

from chekhov.cli import checks
from chekhov.errors import ChekhovError


def _cmd_view(args: argparse.Namespace) -> int:
    try:
        import viser  # noqa: F401
    except ImportError as e:
        raise ChekhovError("chekhov view needs the viewer extra: pip install 'chekhov[viewer]' "
                           f"({e})") from e
    if args.react:
        return _cmd_view_react(args)
    from chekhov.scene.io import load_scene
    from chekhov.viewer.app import check_port_free

    if args.cases is not None and args.n_cases is not None:
        raise ChekhovError("give --cases FILE or --n-cases N, not both")
    for flag, value in (("--cases", args.cases), ("--roadmap", args.roadmap)):
        if value is not None:
            checks.input_file(value, flag)
    load_scene(args.scene)
    check_port_free(args.host, args.port)  # fail fast, before loading anything
    from chekhov.cases import CaseSet, cached_cases
    from chekhov.roadmap.io import load_or_build_roadmap, load_roadmap
    from chekhov.viewer.app import Viewer
    from chekhov.world import World

    world = World.load(args.scene)
    roadmap = (load_roadmap(args.roadmap, world) if args.roadmap
               else load_or_build_roadmap(world, progress=lambda s: print(s, flush=True)))
    cases = (CaseSet.load(args.cases, world) if args.cases
             else cached_cases(world, args.n_cases or 20))
    viewer = Viewer(world, roadmap, cases, host=args.host, port=args.port,
                    show_spheres=args.spheres, show_roadmap=not args.hide_roadmap,
                    show_edges=args.edges)
    print(f"chekhov viewer: {viewer.url}  ({world.scene.name}; Ctrl-C to stop)", flush=True)
    viewer.serve_forever()
    return 0


def _cmd_view_react(args: argparse.Namespace) -> int:
    """``chekhov view SCENE --react``: the reactive executive, live."""
    from chekhov.scene.io import load_scene
    from chekhov.viewer.app import check_port_free

    for flag, value in (("--roadmap", args.roadmap), ("--cases", args.cases),
                        ("--n-cases", args.n_cases)):
        if value is not None:
            raise ChekhovError(f"{flag} is for planning in the viewer, not for --react (the "
                               "executive plans with the cached roadmap, on scripted episodes)")
    load_scene(args.scene)
    check_port_free(args.host, args.port)  # fail fast, before loading anything
    from chekhov.viewer.react_app import open_react_viewer

    viewer = open_react_viewer(args.scene, host=args.host, port=args.port,
                               progress=lambda s: print(s, flush=True))
    print(f"chekhov viewer: {viewer.url}  ({viewer.world.scene.name}, reactive executive; "
          "Ctrl-C to stop)", flush=True)
    viewer.serve_forever()
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``view`` to the top-level parser."""
    p = sub.add_parser("view", help="interactive 3D viewer in the browser (viser): plan, "
                                    "drag obstacles, watch it replan")
    p.add_argument("scene", help="built-in scene name or scene YAML file")
    p.add_argument("--roadmap", metavar="FILE",
                   help="roadmap file (default: the cached roadmap, built if missing)")
    p.add_argument("--cases", metavar="FILE", help="case file (default: 20 cached cases, seed 0)")
    p.add_argument("--n-cases", type=checks.int_at_least(1, 1000), metavar="N",
                   help="cached cases of seed 0 when no --cases file (default 20)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default "
                                                       "localhost only)")
    p.add_argument("--port", type=checks.PORT, default=8080, metavar="PORT",
                   help="port, 1..65535 (default 8080)")
    p.add_argument("--spheres", action="store_true", help="show the collision spheres")
    p.add_argument("--hide-roadmap", action="store_true",
                   help="start with the roadmap's nodes hidden (a GUI checkbox shows them)")
    p.add_argument("--edges", action="store_true",
                   help="start with the roadmap's edges shown (dense: off by default)")
    p.add_argument("--react", action="store_true",
                   help="run the reactive executive live instead: the arm moves at 100 Hz "
                        "through scripted episodes while a forearm sweeps across (drag the "
                        "orange cylinder into its way too); shows the mode, the reaction "
                        "latency, replans and safe stops")
    p.set_defaults(func=_cmd_view)
