"""View a scene in the browser, plan, and watch Roadmap + TrajOpt replan around a moving arm.

Run it, open the printed address (http://127.0.0.1:8080 by default) in a browser:

    python examples/03_viewer.py [SCENE] [--port 8080] [--sweep]

What you see: the scene's objects coloured by semantic class (the draggable dynamic obstacle,
a person's forearm, in orange-red), Baxter with its URDF meshes, the roadmap's nodes as
end-effector positions, the start (green) and goal (red gizmo) of case 0, the roadmap seed
(orange) and the optimised trajectory (blue), animated with the time slider. The GUI panel picks
cases and planners (Roadmap+TrajOpt, TrajOpt, RRTConnect, RRTConnect+TrajOpt) and shows the
timing breakdown and path length. Drag the obstacle's gizmo: every move replans.

With ``--sweep`` the script moves the obstacle itself, from Python, across the first plan's
end-effector path, and prints each replanning time — the same thing the gizmo does:

    viewer.move_obstacle(T_world_obj)   # world + browser
    view = viewer.replan()              # PlanView: .result (PlanResult), .path, .ee_path

The command line equivalent of the viewer alone is ``chekhov view SCENE``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import chekhov
from chekhov.transforms import make_transform, quat_to_matrix
from chekhov.viewer.app import Viewer


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default="tabletop_pole")
    ap.add_argument("--port", type=int, default=8080)
    ap.add_argument("--sweep", action="store_true", help="move the obstacle from Python")
    args = ap.parse_args()

    world = chekhov.World.load(args.scene)
    roadmap = chekhov.load_or_build_roadmap(world)        # cached on disk after the first run
    viewer = Viewer(world, roadmap, port=args.port)       # plans case 0 on start
    print(f"open {viewer.url}  (Ctrl-C to stop)")
    if args.sweep and viewer.view is not None and viewer.view.ee_path is not None:
        ee = viewer.view.ee_path
        R = viewer.obstacles[viewer.obstacle_name or ""].wxyz
        for p in ee[len(ee) // 4: 3 * len(ee) // 4: max(1, len(ee) // 10)]:
            T = make_transform(p, quat_to_matrix(tuple(R)))
            viewer.move_obstacle(T)
            view = viewer.replan()
            print(f"obstacle at {np.round(p, 2)}: {view.result.status} in "
                  f"{1e3 * view.result.time_s:.0f} ms")
            time.sleep(1.0)
    viewer.serve_forever()


if __name__ == "__main__":
    main()
