"""The paper's numbers (Dai et al., "Improving Trajectory Optimization using a Roadmap
Framework"), typed in from its Tables I–IV, to print beside ours.

Units: failure and collision rates as fractions (the paper prints percentages), runtimes in s,
path lengths in rad. 5000 cases per scene; time limit 300 s. The paper's "RRT" is OpenRAVE's
BasicRRT, a bidirectional RRT: our ``RRTConnect``. Its LazyPRM, RRT* and PRM* are OMPL's.
Only "tabletop with a pole" and "shelf with boxes" appear in Tables I, II and IV; Table III
has all four scenes.
"""

from __future__ import annotations

PAPER_TIME_LIMIT_S = 300.0
PAPER_CASES = 5000

# our scene name -> the paper's environment name
SCENE_TITLES = {"tabletop_pole": "Tabletop with a Pole",
                "tabletop_container": "Tabletop with a Container",
                "kitchen": "Kitchen", "shelf_boxes": "Shelf with Boxes"}

# our planner name -> the paper's row name
PAPER_PLANNER = {"RRTConnect": "RRT", "LazyPRM": "LazyPRM", "RRT*": "RRT*", "PRM*": "PRM*",
                 "TrajOpt": "TrajOpt", "Roadmap+TrajOpt": "Roadmap",
                 "Roadmap+TrajOpt(paper)": "Roadmap"}

# Table I: Evaluation of current sampling-based and trajectory optimization planners.
# (failure rate, average runtime s, average path length rad)
TABLE_I: dict[str, dict[str, tuple[float, float, float]]] = {
    "tabletop_pole": {
        "RRT": (0.0230, 17.88, 0.77),
        "LazyPRM": (0.0022, 7.32, 1.76),
        "RRT*": (0.0532, 300.19, 0.63),
        "PRM*": (0.0100, 300.71, 0.79),
        "TrajOpt": (0.1738, 0.56, 0.71),
    },
    "shelf_boxes": {
        "RRT": (0.1000, 63.86, 1.06),
        "LazyPRM": (0.1694, 63.85, 2.08),
        "RRT*": (0.2678, 300.37, 0.93),
        "PRM*": (0.2434, 300.79, 1.16),
        "TrajOpt": (0.3206, 1.59, 1.51),
    },
}

# Table II: Performance of the combined "sampling-based seed + TrajOpt" planner.
# seed planner -> (average TrajOpt runtime s, average runtime s, average path length rad,
# collision rate)
TABLE_II: dict[str, dict[str, tuple[float, float, float, float]]] = {
    "tabletop_pole": {
        "RRT": (0.63, 18.51, 0.70, 0.0129),
        "LazyPRM": (0.98, 8.30, 1.28, 0.0012),
        "RRT*": (0.29, 300.48, 0.54, 0.0002),
        "PRM*": (0.36, 301.07, 0.64, 0.0010),
    },
    "shelf_boxes": {
        "RRT": (0.92, 64.78, 0.98, 0.0420),
        "LazyPRM": (1.36, 65.21, 1.60, 0.0157),
        "RRT*": (0.46, 300.83, 0.81, 0.0117),
        "PRM*": (0.67, 301.46, 0.95, 0.0198),
    },
}

# Table III: Roadmap performance in all environments.
# (failure rate, average runtime s, average path length rad, best average rad = the shortest
# average path length of the sampling-based planners in that scene)
TABLE_III: dict[str, tuple[float, float, float, float]] = {
    "tabletop_pole": (0.0018, 0.14, 1.24, 0.63),
    "tabletop_container": (0.0076, 0.18, 1.32, 0.80),
    "kitchen": (0.0192, 0.38, 1.29, 0.71),
    "shelf_boxes": (0.1206, 0.39, 1.30, 0.93),
}

# Table IV: TrajOpt seeded with a sampling-based planner's solution compared to the roadmap's.
# seed planner -> (average TrajOpt runtime s, average seed length rad, average runtime s,
# average path length rad, collision rate). (The paper's RRT runtime in the shelf is 64.87
# here and 64.78 in Table II; both as printed.)
TABLE_IV: dict[str, dict[str, tuple[float, float, float, float, float]]] = {
    "tabletop_pole": {
        "RRT": (0.63, 0.77, 18.51, 0.70, 0.0129),
        "LazyPRM": (0.98, 1.76, 8.30, 1.28, 0.0012),
        "RRT*": (0.29, 0.63, 300.48, 0.54, 0.0002),
        "Roadmap": (0.45, 1.24, 0.59, 0.82, 0.0006),
    },
    "shelf_boxes": {
        "RRT": (0.92, 1.06, 64.87, 0.98, 0.0420),
        "LazyPRM": (1.36, 2.08, 65.21, 1.60, 0.0157),
        "RRT*": (0.46, 0.93, 300.83, 0.81, 0.0117),
        "Roadmap": (0.61, 1.30, 1.00, 1.02, 0.0198),
    },
}
