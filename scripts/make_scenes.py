"""Regenerate the built-in scene files in src/chekhov/scene/data/ (a developer tool).

    python scripts/make_scenes.py [--kitchen PATH_TO/kitchen.env.xml]

The kitchen comes from the TrajOpt package's ``data/kitchen.env.xml`` (OpenRAVE format: box
``extents`` are half extents, ``translation`` the centre, ``quat`` w x y z); every box is kept
with its extents and position and given a semantic class. The other three Baxter scenes are
designed here for the Baxter left arm, as described in the paper; the two Panda scenes
(``panda_table_shelf``, ``panda_cage``) for a Franka Panda on a bench, reaching under a shelf
board and into an enclosure open towards it. chekhov never reads the XML at run time.
"""

from __future__ import annotations

import argparse
import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import yaml

OUT = Path(__file__).resolve().parents[1] / "src" / "chekhov" / "scene" / "data"
BASE = {"xyz": [0.0, 0.0, 0.93], "rpy": [0.0, 0.0, 0.0]}  # Baxter base frame 0.93 m above floor


def box(name: str, cls: str, size: list[float], xyz: list[float], **extra: Any) -> dict[str, Any]:
    d: dict[str, Any] = {"name": name, "class": cls, "shape": "box",
                         "size": [round(s, 4) for s in size],
                         "pose": {"xyz": [round(v, 4) for v in xyz], "rpy": [0, 0, 0]}}
    d.update(extra)
    return d


def table(top_z: float = 0.75, cx: float = 0.85, cy: float = 0.25, sx: float = 0.8,
          sy: float = 1.5) -> list[dict[str, Any]]:
    t = 0.04
    objs = [box("tabletop", "table", [sx, sy, t], [cx, cy, top_z - t / 2])]
    leg_h = top_z - t
    for i, (dx, dy) in enumerate([(-1, -1), (-1, 1), (1, -1), (1, 1)]):
        objs.append({"name": f"table_leg_{i}", "class": "table", "shape": "cylinder",
                     "size": [0.03, round(leg_h, 4)],
                     "pose": {"xyz": [round(cx + dx * (sx / 2 - 0.06), 4),
                                      round(cy + dy * (sy / 2 - 0.06), 4), round(leg_h / 2, 4)],
                              "rpy": [0, 0, 0]}})
    return objs


GRASP_BOX = [{"generate": {"approaches": ["top", "front"], "standoff": 0.10, "depth": 0.03}}]

# Things to pick (issue 17), standing upright: (class, shape, size): cylinder (radius, height),
# box (x, y, z) full lengths.
ITEMS: dict[str, tuple[str, str, list[float]]] = {
    "cup": ("object", "cylinder", [0.04, 0.10]),
    "can": ("object", "cylinder", [0.033, 0.12]),
    "bottle": ("object", "cylinder", [0.035, 0.20]),
    "jar": ("object", "cylinder", [0.045, 0.12]),
    "carton": ("box", "box", [0.07, 0.07, 0.16]),
    "pack": ("box", "box", [0.06, 0.10, 0.10]),
}


def item(name: str, kind: str, xy: tuple[float, float], z: float, approaches: list[str],
         yaw: float = 0.0, standoff: float = 0.10, depth: float = 0.03) -> dict[str, Any]:
    """A graspable ``kind`` (see ITEMS) standing on a surface at height ``z`` (m), centred at
    ``xy``, turned by ``yaw`` (rad) about the vertical; one generated grasp per approach
    (object frame: ``front`` moves along +x, ``left`` along -y, ``right`` along +y)."""
    cls, shape, size = ITEMS[kind]
    height = size[-1]
    return {"name": name, "class": cls, "shape": shape, "size": size,
            "pose": {"xyz": [round(xy[0], 4), round(xy[1], 4), round(z + height / 2, 4)],
                     "rpy": [0, 0, round(yaw, 6)]},
            "grasps": [{"generate": {"approaches": approaches, "standoff": standoff,
                                     "depth": depth}}]}


def tabletop_pole() -> dict[str, Any]:
    objs = table()
    objs.append({"name": "pole", "class": "pole", "shape": "cylinder", "size": [0.03, 0.7],
                 "pose": {"xyz": [0.80, 0.30, 1.10], "rpy": [0, 0, 0]}})
    objs.append(box("box_left", "box", [0.10, 0.10, 0.16], [0.75, 0.68, 0.83], grasps=GRASP_BOX))
    objs.append(box("box_right", "box", [0.10, 0.10, 0.16], [0.75, -0.08, 0.83], grasps=GRASP_BOX))
    z = 0.75  # table top
    objs += [  # around the pole (the arm does not reach behind it), and along the table
        item("cup_0", "cup", (0.66, 0.38), z, ["top", "front"]),
        item("cup_1", "cup", (0.68, 0.18), z, ["top", "front"]),
        item("bottle_0", "bottle", (0.82, 0.45), z, ["top"]),
        item("can_0", "can", (0.80, 0.15), z, ["top"]),
        item("carton_0", "carton", (0.58, 0.60), z, ["top"]),
        item("pack_0", "pack", (0.60, -0.32), z, ["top"]),
        item("cup_2", "cup", (0.55, 0.82), z, ["top", "front"]),
    ]
    return {"name": "tabletop_pole",
            "description": "Tabletop pick-and-place: a slender pole in the middle of the table "
                           "and a box on each side of it; cups, cans and bottles around it and "
                           "along the table.",
            "robot": "baxter_left", "base_pose": BASE, "objects": objs,
            "regions": [{"name": "above_table", "center": [0.85, 0.25, 1.0],
                         "size": [0.8, 1.5, 0.5], "weight": 3.0}]}


def tabletop_container() -> dict[str, Any]:
    objs = table()
    cx, cy, w, d, h, t, z0 = 0.82, 0.32, 0.45, 0.60, 0.22, 0.015, 0.75
    objs += [
        box("container_bottom", "container", [w, d, t], [cx, cy, z0 + t / 2]),
        box("container_front", "container", [t, d, h], [cx - w / 2 + t / 2, cy, z0 + h / 2]),
        box("container_back", "container", [t, d, h], [cx + w / 2 - t / 2, cy, z0 + h / 2]),
        box("container_left", "container", [w, t, h], [cx, cy + d / 2 - t / 2, z0 + h / 2]),
        box("container_right", "container", [w, t, h], [cx, cy - d / 2 + t / 2, z0 + h / 2]),
        box("box_in_0", "box", [0.08, 0.08, 0.12], [cx - 0.08, cy - 0.14, z0 + t + 0.06],
            grasps=[{"generate": {"approaches": ["top"], "standoff": 0.12, "depth": 0.03}}]),
        box("box_in_1", "box", [0.08, 0.10, 0.10], [cx + 0.07, cy + 0.13, z0 + t + 0.05],
            grasps=[{"generate": {"approaches": ["top"], "standoff": 0.12, "depth": 0.03}}]),
        box("box_out_0", "box", [0.10, 0.10, 0.14], [0.70, -0.20, z0 + 0.07], grasps=GRASP_BOX),
        box("box_out_1", "box", [0.10, 0.10, 0.14], [0.68, 0.85, z0 + 0.07], grasps=GRASP_BOX),
    ]
    floor = z0 + t
    objs += [  # in the container (the arm reaches its front half from above), beside it
        item("cup_in_0", "cup", (0.70, 0.46), floor, ["top"]),
        item("cup_in_1", "cup", (0.78, 0.55), floor, ["top"]),
        item("can_in_0", "can", (0.83, 0.30), floor, ["top"]),
        item("jar_in_0", "jar", (0.69, 0.30), floor, ["top"]),
        item("cup_out_0", "cup", (0.58, -0.32), z0, ["top"]),
        item("bottle_out_0", "bottle", (0.80, -0.08), z0, ["top"]),
        item("carton_out_0", "carton", (0.55, 0.75), z0, ["top", "front"]),
        item("pack_out_0", "pack", (0.70, 0.665), z0, ["top"], yaw=math.pi / 2),
    ]
    return {"name": "tabletop_container",
            "description": "A table with a large open container; boxes, cups and cans in it and "
                           "beside it.",
            "robot": "baxter_left", "base_pose": BASE, "objects": objs,
            "regions": [{"name": "above_table", "center": [0.85, 0.25, 1.0],
                         "size": [0.8, 1.5, 0.5], "weight": 2.0},
                        {"name": "inside_container", "center": [cx, cy, z0 + 0.15],
                         "size": [w - 0.05, d - 0.05, 0.2], "weight": 3.0}]}


def shelf_boxes() -> dict[str, Any]:
    x0, depth, y0, width, t = 0.68, 0.36, -0.25, 1.10, 0.02
    levels = [0.62 + 0.21 * k for k in range(7)]  # top surface of each level's board
    roof = levels[-1] + 0.21
    cx, cy = x0 + depth / 2, y0 + width / 2
    objs = [box(f"board_{k}", "shelf", [depth, width, t], [cx, cy, z - t / 2])
            for k, z in enumerate(levels)]
    objs.append(box("roof", "shelf", [depth, width, t], [cx, cy, roof + t / 2]))
    objs.append(box("side_left", "shelf", [depth, t, roof + t], [cx, y0 + width + t / 2,
                                                                   (roof + t) / 2]))
    objs.append(box("side_right", "shelf", [depth, t, roof + t], [cx, y0 - t / 2, (roof + t) / 2]))
    objs.append(box("back", "shelf", [t, width + 2 * t, roof + t], [x0 + depth + t / 2, cy,
                                                                     (roof + t) / 2]))
    regions = []
    for k, z in enumerate(levels):
        # two boxes a level, at positions that change from level to level
        for j, (fy, sx, sy, sz) in enumerate([(0.18 + 0.09 * (k % 3), 0.09, 0.09, 0.12),
                                              (0.68 - 0.07 * (k % 4), 0.08, 0.12, 0.10)]):
            objs.append(box(f"box_{k}_{j}", "box", [sx, sy, sz],
                            [x0 + depth - 0.08, y0 + fy * width, z + sz / 2],
                            grasps=[{"generate": {"approaches": ["front"], "standoff": 0.10,
                                                  "depth": 0.03}}]))
        # things to pick (issue 17): a can between the two boxes, as deep as they stand, and a
        # carton nearer the front on the boxes' left
        y_between = y0 + width * (0.18 + 0.09 * (k % 3) + 0.68 - 0.07 * (k % 4)) / 2
        objs.append(item(f"can_{k}_0", "can", (x0 + depth - 0.12, y_between), z, ["front"]))
        objs.append(item(f"carton_{k}_1", "carton", (x0 + 0.16, y0 + 0.79 * width), z,
                         ["front"]))
        regions.append({"name": f"level_{k}", "center": [round(cx, 4), round(cy, 4),
                                                        round(z + 0.095, 4)],
                        "size": [depth, width, 0.17], "weight": 2.0})
    return {"name": "shelf_boxes",
            "description": "A 7-level shelf with two boxes, a can between them and a carton "
                           "on each level (narrow gaps: the hard scene).",
            "robot": "baxter_left", "base_pose": BASE, "objects": objs, "regions": regions}


PANDA_FINGERS = {"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04}   # open, m
PANDA_BASE = {"xyz": [0.0, 0.0, 0.0], "rpy": [0.0, 0.0, 0.0]}


def bench(x0: float = 0.22, x1: float = 0.95, width: float = 1.3) -> list[dict[str, Any]]:
    """A bench top at z = 0 (the Panda's base height) in front of the robot, from x0 to x1."""
    return [box("bench", "table", [x1 - x0, width, 0.04], [(x0 + x1) / 2, 0.0, -0.02])]


def panda_table_shelf() -> dict[str, Any]:
    """Objects to pick on a bench, two of them under a shelf board held by two side panels."""
    top = [{"generate": {"approaches": ["top", "front"], "standoff": 0.10, "depth": 0.03}}]
    front = [{"generate": {"approaches": ["front"], "standoff": 0.10, "depth": 0.03}}]
    sx, sy, sz, w, t = 0.62, 0.30, 0.32, 0.50, 0.02   # shelf centre x, y, board height, width
    objs = [
        *bench(),
        box("shelf_board", "shelf", [0.30, w, t], [sx, sy, sz + t / 2]),
        box("shelf_side_0", "shelf", [0.30, t, sz], [sx, sy - w / 2 + t / 2, sz / 2]),
        box("shelf_side_1", "shelf", [0.30, t, sz], [sx, sy + w / 2 - t / 2, sz / 2]),
        box("under_0", "box", [0.06, 0.06, 0.12], [sx - 0.02, sy - 0.10, 0.06], grasps=front),
        box("under_1", "box", [0.05, 0.08, 0.09], [sx + 0.03, sy + 0.10, 0.045], grasps=front),
        box("on_shelf", "box", [0.06, 0.06, 0.10], [sx, sy, sz + t + 0.05], grasps=top),
        box("open_0", "box", [0.06, 0.06, 0.12], [0.45, -0.15, 0.06], grasps=top),
        box("open_1", "box", [0.05, 0.05, 0.16], [0.60, -0.35, 0.08], grasps=top),
        {"name": "can", "class": "box", "shape": "cylinder", "size": [0.035, 0.12],
         "pose": {"xyz": [0.40, 0.05, 0.06], "rpy": [0, 0, 0]},
         "grasps": [{"generate": {"approaches": ["top"], "standoff": 0.10, "depth": 0.03}}]},
        # issue 17: more on and under the board, and in the open
        item("on_shelf_cup", "cup", (sx - 0.03, sy - 0.15), sz + t, ["top", "front"]),
        item("under_can", "can", (sx - 0.04, sy), 0.0, ["front"]),
        item("open_bottle", "bottle", (0.40, -0.55), 0.0, ["top", "front"]),
        item("open_cup", "cup", (0.68, -0.08), 0.0, ["top"]),
    ]
    return {"name": "panda_table_shelf",
            "description": "A Franka Panda at a bench: objects to pick in the open, on a shelf "
                           "board and under it (reach in below the board).",
            "robot": "panda", "base_pose": PANDA_BASE, "locked_joints": PANDA_FINGERS,
            "objects": objs,
            "regions": [{"name": "above_bench", "center": [0.5, -0.2, 0.25],
                         "size": [0.5, 0.6, 0.4], "weight": 2.0},
                        {"name": "under_shelf", "center": [sx, sy, 0.17],
                         "size": [0.28, w - 0.06, 0.2], "weight": 3.0}]}


def panda_cage() -> dict[str, Any]:
    """An enclosure (a cage) on the bench, open towards the robot with a bar across the
    opening: objects inside to reach past the bar, others beside it."""
    top = [{"generate": {"approaches": ["top", "front"], "standoff": 0.10, "depth": 0.03}}]
    front = [{"generate": {"approaches": ["front"], "standoff": 0.10, "depth": 0.03}}]
    x0, x1, w, h, t = 0.42, 0.78, 0.46, 0.42, 0.02   # open face at x0, back wall at x1
    cx, cy = (x0 + x1) / 2, 0.05
    objs = [
        *bench(),
        box("cage_back", "container", [t, w, h], [x1 - t / 2, cy, h / 2]),
        box("cage_side_0", "container", [x1 - x0, t, h], [cx, cy - w / 2 + t / 2, h / 2]),
        box("cage_side_1", "container", [x1 - x0, t, h], [cx, cy + w / 2 - t / 2, h / 2]),
        box("cage_roof", "container", [x1 - x0, w, t], [cx, cy, h + t / 2]),
        {"name": "cage_bar", "class": "container", "shape": "cylinder", "size": [0.012, w],
         "pose": {"xyz": [x0 + 0.01, cy, 0.30], "rpy": [round(math.pi / 2, 6), 0, 0]}},
        box("inside_0", "box", [0.06, 0.06, 0.12], [cx + 0.03, cy - 0.10, 0.06], grasps=front),
        box("inside_1", "box", [0.05, 0.07, 0.14], [cx + 0.06, cy + 0.08, 0.07], grasps=front),
        box("beside_0", "box", [0.06, 0.06, 0.12], [0.45, -0.36, 0.06], grasps=top),
        box("beside_1", "box", [0.06, 0.08, 0.10], [0.40, 0.42, 0.05], grasps=top),
        # issue 17: more beside the cage (inside, the hand has room for the two boxes only)
        item("beside_cup", "cup", (0.55, -0.55), 0.0, ["top", "front"]),
        item("beside_bottle", "bottle", (0.60, -0.40), 0.0, ["top"]),
        item("beside_jar", "jar", (0.38, 0.60), 0.0, ["top"]),
        item("beside_can", "can", (0.65, 0.45), 0.0, ["top"]),
        item("beside_pack", "pack", (0.50, 0.55), 0.0, ["top"]),
    ]
    return {"name": "panda_cage",
            "description": "A Franka Panda at a bench with a cage open towards it and a bar "
                           "across the opening: reach in past the bar; boxes, cups "
                           "and bottles beside the cage.",
            "robot": "panda", "base_pose": PANDA_BASE, "locked_joints": PANDA_FINGERS,
            "objects": objs,
            "regions": [{"name": "inside_cage", "center": [cx, cy, 0.15],
                         "size": [x1 - x0 - 0.06, w - 0.06, 0.2], "weight": 3.0},
                        {"name": "beside_cage", "center": [0.45, 0.0, 0.2],
                         "size": [0.3, 0.9, 0.3], "weight": 1.0}]}


KITCHEN_CLASSES = [
    ("dishwasher_door", "door"), ("dishwasher_handle", "handle"), ("freezer_handle", "handle"),
    ("fridge_door", "door"), ("freezer_door", "door"), ("fridge", "fridge"),
    ("countertop", "counter"), ("sink", "sink"), ("back_wall", "wall"),
    ("dishwasher", "appliance"), ("faucet", "appliance"), ("knob", "handle"),
    ("cabinet", "cabinet"), ("table", "table"),
]


def kitchen_items() -> list[dict[str, Any]]:
    """Things to pick in the kitchen (issue 17), turned to face the robot (it stands at
    x = 1.05 looking along -x: ``front`` grasps move along -x). The wall cabinet (x < 0.4,
    from z = 1.19) hangs over the back of the counter, so things under it are taken from the
    front, things at the counter's edge from above too."""
    face = math.pi
    counter, sink, fridge = 0.76, 0.51, (0.61, 0.93, 1.24)   # surfaces, m
    cabinet = (1.21, 1.56)
    return [
        item("counter_cup_0", "cup", (0.52, 0.85), counter, ["top", "front"], face),
        item("counter_cup_1", "cup", (0.50, 1.00), counter, ["top", "front"], face),
        item("counter_carton_0", "carton", (0.28, 1.12), counter, ["front"], face),
        item("counter_bottle_0", "bottle", (0.25, 1.25), counter, ["front"], face),
        item("sink_cup_0", "cup", (0.45, 1.45), sink, ["top"], face),
        item("sink_cup_1", "cup", (0.50, 1.55), sink, ["top"], face),
        item("sink_jar_0", "jar", (0.36, 1.40), sink, ["top"], face),
        item("fridge_bottle_1", "bottle", (0.48, 0.55), fridge[0], ["front"], face),
        item("fridge_bottle_0", "bottle", (0.42, 0.50), fridge[1], ["front"], face),
        item("fridge_carton_0", "carton", (0.40, 0.30), fridge[1], ["front"], face),
        item("fridge_jar_0", "jar", (0.40, 0.50), fridge[2], ["front"], face),
        item("fridge_can_0", "can", (0.42, 0.30), fridge[2], ["front"], face),
        item("cabinet_cup_0", "cup", (0.22, 0.90), cabinet[0], ["front"], face),
        item("cabinet_pack_0", "pack", (0.22, 1.20), cabinet[0], ["front"], face),
        item("cabinet_jar_0", "jar", (0.22, 1.00), cabinet[1], ["front"], face),
        item("cabinet_can_0", "can", (0.22, 0.85), cabinet[1], ["front"], face),
    ]


def kitchen(xml_path: Path) -> dict[str, Any]:
    root = ET.parse(xml_path).getroot()
    hinge_world = (0.60, 0.16)  # dishwasher door hinge: its front bottom edge (x, z)
    objs = []
    for kb in root.findall("KinBody"):
        geoms = list(kb.iter("Geom"))
        for gi, g in enumerate(geoms):
            if g.get("type") != "box":
                raise ValueError(f"{xml_path}: {kb.get('name')}: only boxes are expected")
            ext = [float(v) for v in (g.findtext("extents") or "").split()]
            xyz = [float(v) for v in (g.findtext("translation") or "").split()]
            quat = [float(v) for v in (g.findtext("quat") or "1 0 0 0").split()]
            name = str(kb.get("name")) + (f"_{gi}" if len(geoms) > 1 else "")
            cls = next(c for key, c in KITCHEN_CLASSES if key in name or (key == "table" and
                       name.startswith("table")))
            d: dict[str, Any] = {"name": name, "class": cls, "shape": "box",
                                 "size": [round(2 * e, 6) for e in ext],
                                 "pose": {"xyz": xyz, "quat": quat}}
            if name.startswith("dishwasher_door") or name.startswith("dishwasher_handle"):
                d["articulation"] = {
                    "type": "hinge", "axis": [0, 1, 0],
                    "origin": [round(hinge_world[0] - xyz[0], 6), 0.0,
                               round(hinge_world[1] - xyz[2], 6)],
                    "states": {"open": 0.0, "closed": round(-math.pi / 2, 6)}, "state": "open"}
            if name == "dishwasher_handle":
                d["grasps"] = [{"generate": {"approaches": ["bottom"], "standoff": 0.10,
                                             "depth": 0.0}}]
            if name == "freezer_handle":
                d["grasps"] = [{"generate": {"approaches": ["back"], "standoff": 0.10,
                                             "depth": 0.0}}]
            objs.append(d)
    objs += kitchen_items()
    return {"name": "kitchen",
            "description": "The kitchen of the TrajOpt package (50 boxes, kept as given), Baxter "
                           "facing the counter between the fridge and the sink; things to pick "
                           "on the counter, in the sink, in the fridge and the wall cabinet.",
            "robot": "baxter_left",
            "base_pose": {"xyz": [1.05, 1.25, 0.93], "rpy": [0.0, 0.0, round(math.pi, 9)]},
            "objects": objs,
            "regions": [
                {"name": "above_countertop_left", "center": [0.3, 1.01, 0.95],
                 "size": [0.58, 0.58, 0.38], "weight": 3.0},
                {"name": "in_sink", "center": [0.3, 1.6, 0.7], "size": [0.56, 0.56, 0.36],
                 "weight": 2.0},
                {"name": "fridge_shelves", "center": [0.3, 0.36, 1.07], "size": [0.56, 0.66, 0.5],
                 "weight": 1.0},
                {"name": "upper_cabinet_low", "center": [0.2, 1.2, 1.375],
                 "size": [0.38, 0.8, 0.33], "weight": 1.0}]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--kitchen", type=Path,
                    default=Path(__file__).resolve().parents[2] / "shared/data/kitchen.env.xml")
    args = ap.parse_args()
    for scene in (tabletop_pole(), tabletop_container(), shelf_boxes(), kitchen(args.kitchen),
                  panda_table_shelf(), panda_cage()):
        path = OUT / f"{scene['name']}.yaml"
        head = f"# {scene['name']}: generated by scripts/make_scenes.py; format in README.md\n"
        path.write_text(head + yaml.safe_dump({"format": 1, **scene}, sort_keys=False,
                                              default_flow_style=None, width=100))
        print(f"wrote {path} ({len(scene['objects'])} objects)")


if __name__ == "__main__":
    main()
