"""``chekhov view SCENE --react``: the reactive executive, live in the browser (viser).

The robot follows the commands of a :class:`~chekhov.viewer.react.LiveExecutive` (100 Hz on the
wall clock, episode after episode) while the episode's forearm moves along its script; the
orange cylinder can be dragged into the arm's way (the sensor reports it). The panel shows the
mode, the latency of the last reaction, and the replans and safe stops; a blue line is the end
effector's way along the commanded rest of the motion, redrawn whenever the motion changes.
The drawing runs on a thread of its own at ``fps``, from the loop's snapshots.

    from chekhov.viewer.react_app import open_react_viewer
    viewer = open_react_viewer("tabletop_pole", port=8080)   # serving at viewer.url
    viewer.serve_forever()
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import viser
from numpy.typing import NDArray

from chekhov.scene.model import Pose, SceneObject, Shape
from chekhov.transforms import make_transform, rotation_about
from chekhov.viewer.app import (
    OBSTACLE_NAME,
    OBSTACLE_SHAPE,
    ViewerError,
    check_port_free,
    serve_until_stopped,
    start_server,
)
from chekhov.viewer.draw import (
    PATH_RGB,
    RobotDrawing,
    draw_draggable,
    draw_object,
    draw_scene,
    draw_trace,
)
from chekhov.viewer.meshes import RobotMeshes, se3_to_wxyz_xyz
from chekhov.viewer.planning import polyline_segments
from chekhov.viewer.react import (
    EeTrace,
    LiveConfig,
    LiveExecutive,
    LiveState,
    counters_markdown,
    latency_markdown,
    status_markdown,
)
from chekhov.world import World

Array = NDArray[np.float64]


def parked_pose(world: World) -> Array:
    """T_world_obj of the draggable obstacle until it is dragged: lying along the robot's
    forward axis, in front of it and to its right, 0.25 m beyond the reach of its arm
    (``robot.reach``) at shoulder height less 0.4 m: in view, and in every sensor frame
    without ever being in the arm's way (nor within the executive's margin of it)."""
    robot = world.robot
    shoulder, reach = robot.reach
    Tb = robot.T_world_base
    a = np.deg2rad(-35.0)
    d = Tb[:3, :3] @ np.array([np.cos(a), np.sin(a), 0.0])
    d[2] = 0.0
    d /= max(float(np.linalg.norm(d)), 1e-9)
    p = shoulder + (reach + 0.25) * d - np.array([0.0, 0.0, 0.4])
    R = Tb[:3, :3] @ rotation_about((0.0, 1.0, 0.0), np.pi / 2)
    return make_transform(p, R)


class ReactViewer:
    """A viser server showing a :class:`LiveExecutive` at work.

    Args:
        world: the world drawn (its scene and robot; the loop has worlds of its own).
        loop: the real-time executive (started here, closed by :meth:`close`); default: one
            over two new worlds of ``world``'s scene.
        host, port: where to listen (0: any free port); a taken port raises ViewerError.
        fps: Hz, how often the robot, the forearm and the panel are redrawn.
        obstacle: the draggable obstacle's shape (a forearm cylinder), reported in every sensor
            frame at its gizmo's pose (``obstacle_pose``, T_world_obj; default
            :func:`parked_pose`, out of the arm's reach); None: none. ``obstacle_name``: its
            name in the frames.
        plain_lighting: no environment map and no shadows: several times quicker to draw
            under software WebGL (a headless browser, a machine without a GPU).

    Attributes:
        handles: scene and GUI handles by name (``"gui/status"``, ``"gui/latency"``,
            ``"gui/counters"``, ``"/react/trace"``, ``"/goal"``, ``"/obstacles/{name}"``).
        shown: the loop's snapshot drawn last (None before the first).
    """

    def __init__(self, world: World, *, loop: LiveExecutive | None = None,
                 host: str = "127.0.0.1", port: int = 8080, fps: float = 30.0,
                 obstacle: Shape | None = OBSTACLE_SHAPE, obstacle_name: str = OBSTACLE_NAME,
                 obstacle_pose: Array | None = None, plain_lighting: bool = False) -> None:
        if port != 0:
            check_port_free(host, port)
        self.world = world
        self.loop = loop if loop is not None else LiveExecutive(
            world=World(world.scene), plan_world=World(world.scene))
        self.server = start_server(world, host=host, port=port)
        if plain_lighting:
            self.server.scene.configure_environment_map(None)
            self.server.scene.configure_default_lights(True, cast_shadow=False)
        self.host, self.port = host, int(self.server.get_port())
        self.fps = fps
        self.handles: dict[str, Any] = {}
        self.shown: LiveState | None = None
        self._stop = threading.Event()
        self._persons: dict[str, tuple[Shape, viser.MeshHandle]] = {}
        self._trace = EeTrace(world.robot)
        self._draw_world()
        self.obstacle_name = obstacle_name if obstacle is not None else None
        self._obstacle_shape = obstacle
        if obstacle is not None:
            self._add_draggable(obstacle, obstacle_name, obstacle_pose)
        self._build_gui()
        self.loop.start()
        self._drawer = threading.Thread(target=self._draw_loop, daemon=True,
                                        name="chekhov-react-draw")
        self._drawer.start()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    def move_obstacle(self, T_world_obj: Array) -> None:
        """Move the draggable obstacle (as a drag would): its gizmo, and the sensor's frames
        from now on."""
        if self.obstacle_name is None or self._obstacle_shape is None:
            raise ViewerError("this viewer has no draggable obstacle")
        T = np.asarray(T_world_obj, dtype=float)
        gizmo = self.handles[f"/obstacles/{self.obstacle_name}"]
        gizmo.wxyz, gizmo.position = se3_to_wxyz_xyz(T)
        self.loop.set_dragged(self.obstacle_name, self._obstacle_shape, T)

    def serve_forever(self) -> None:
        """Block until Ctrl-C (or :meth:`close` from another thread)."""
        serve_until_stopped(self._stop, self.close)

    def close(self) -> None:
        """Stop drawing, the loop and the server."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._drawer.join(2.0)
        self.loop.close()
        self.server.stop()

    def __enter__(self) -> ReactViewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- scene and GUI ----------------------------------------------------------------
    def _draw_world(self) -> None:
        """The scene, the robot where the loop has it, the goal's frame, the trace."""
        state = self.loop.state
        self.handles.update(draw_scene(self.server, self.world))
        self.robot = RobotDrawing(self.server, RobotMeshes(self.world.robot), state.q)
        self.handles["/goal"] = self.server.scene.add_frame(
            "/goal", axes_length=0.08, axes_radius=0.006, origin_radius=0.015,
            origin_color=(220, 40, 40), visible=False)
        self.handles["/react/trace"] = draw_trace(self.server, "/react/trace", None, PATH_RGB,
                                                  4.0)

    def _add_draggable(self, shape: Shape, name: str, pose: Array | None) -> None:
        """The draggable obstacle, reported to the loop at once and on every drag."""
        T = parked_pose(self.world) if pose is None else np.asarray(pose, dtype=float)

        def on_move(T_world_obj: Array) -> None:
            self.loop.set_dragged(name, shape, T_world_obj)

        obj = SceneObject(name, shape, Pose(), "person", dynamic=True)
        gizmo, mesh = draw_draggable(self.server, obj, T, on_move)
        self.handles[f"/obstacles/{name}"], self.handles[f"/obstacles/{name}/mesh"] = gizmo, mesh
        self.loop.set_dragged(name, shape, T)

    def _build_gui(self) -> None:
        gui = self.server.gui
        h = self.handles
        gui.add_markdown(f"**chekhov** · `{self.world.scene.name}` · reactive executive, "
                         f"{round(1 / self.loop.config.react.executor.control_dt_s)} Hz")
        with gui.add_folder("Executive"):
            h["gui/status"] = gui.add_markdown(status_markdown(self.loop.state))
            h["gui/latency"] = gui.add_markdown(latency_markdown(None))
            h["gui/counters"] = gui.add_markdown(counters_markdown(self.loop.state))
            h["gui/help"] = gui.add_markdown(
                "A forearm sweeps across the arm's way (red-orange); drag the orange cylinder "
                "into it too. Blue: where the end effector is commanded to go.")

    # --- drawing ----------------------------------------------------------------------
    def _draw_loop(self) -> None:
        while not self._stop.wait(1.0 / self.fps):
            state = self.loop.state
            if state is self.shown:
                continue
            with self.server.atomic():
                self._draw(state)
            self.shown = state

    def _draw(self, state: LiveState) -> None:
        """One snapshot: the robot, the forearm, the goal, the trace (when the commanded motion
        changed), and the panel's texts (when they changed)."""
        self.robot.show(state.q)
        self._draw_persons(state)
        last = self.shown
        if last is None or state.goal is not last.goal:
            self._draw_goal(state)
        if last is None or state.motion is not last.motion:
            pts = None if state.motion is None else self._trace.along(state.motion, state.t)
            trace = self.handles["/react/trace"]
            if pts is not None:
                trace.points = polyline_segments(pts).astype(np.float32)
            trace.visible = pts is not None
        error = self.loop.error
        texts: dict[str, Callable[[], str]] = {
            "gui/status": lambda: status_markdown(state) + (
                f"  \n**loop failed:** {error}" if error else ""),
            "gui/latency": lambda: latency_markdown(state.reaction),
            "gui/counters": lambda: counters_markdown(state)}
        for name, text in texts.items():
            content = text()
            if self.handles[name].content != content:
                self.handles[name].content = content

    def _draw_goal(self, state: LiveState) -> None:
        frame = self.handles["/goal"]
        T = None if state.goal is None else state.goal.T_world_ee
        if T is not None:
            frame.wxyz, frame.position = se3_to_wxyz_xyz(np.asarray(T, dtype=float))
        frame.visible = T is not None

    def _draw_persons(self, state: LiveState) -> None:
        """The script's moving obstacles at their true poses now (hidden when absent)."""
        moving = () if state.script is None else state.script.obstacles
        present = set()
        for m in moving:
            entry = self._persons.get(m.name)
            if entry is None or entry[0] != m.shape:
                if entry is not None:
                    entry[1].remove()
                obj = SceneObject(m.name, m.shape, Pose(), "person", dynamic=True)
                entry = (m.shape, draw_object(self.server, f"/person/{m.name}", obj,
                                              m.pose(state.t)))
                self._persons[m.name] = entry
            if m.present(state.t):
                present.add(m.name)
                entry[1].wxyz, entry[1].position = se3_to_wxyz_xyz(m.pose(state.t))
        for name, (_, handle) in self._persons.items():
            visible = name in present
            if handle.visible != visible:
                handle.visible = visible


def open_react_viewer(scene: str | Path, *, host: str = "127.0.0.1", port: int = 8080,
                      config: LiveConfig | None = None, plain_lighting: bool = False,
                      progress: Callable[[str], None] | None = None) -> ReactViewer:
    """The react viewer of ``scene`` (a built-in name or a YAML file), serving: three worlds
    (one drawn, one for the executive's checks, one for its replans), the roadmap from the
    cache (built, with ``progress``, when missing) and the loop, started. ``host``, ``port``,
    ``plain_lighting``: as :class:`ReactViewer` has them."""
    from chekhov.roadmap.io import load_or_build_roadmap

    world = World.load(scene)
    checks = World.load(scene)
    load_or_build_roadmap(checks, progress=progress)   # the planners load it from the cache
    loop = LiveExecutive(world=checks, plan_world=World.load(scene), config=config)
    try:
        return ReactViewer(world, loop=loop, host=host, port=port,
                           plain_lighting=plain_lighting)
    except BaseException:
        loop.close()
        raise
