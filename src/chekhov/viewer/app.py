"""The interactive 3D viewer (viser, in the browser): plan from the GUI, watch the seed and the
optimised trajectory, drag a dynamic obstacle and see Roadmap + TrajOpt replan on every move.

    from chekhov.viewer.app import Viewer
    v = Viewer(world, roadmap, cases, port=8080)   # serving at v.url
    v.move_obstacle(T)                             # move the dynamic obstacle (and its gizmo)
    view = v.replan()                              # Roadmap + TrajOpt, shown in the browser
    v.close()
"""

from __future__ import annotations

import errno
import socket
import threading
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from chekhov.errors import ChekhovError

try:
    import viser
except ImportError as e:  # pragma: no cover - depends on the install
    raise ChekhovError("the 3D viewer needs the PyPI package 'viser': "
                       "pip install 'chekhov[viewer]'") from e

from chekhov.cases import CaseSet, cached_cases
from chekhov.roadmap.graph import Roadmap
from chekhov.robot.goal import Goal
from chekhov.scene.model import Pose, SceneObject, Shape
from chekhov.transforms import make_transform, rotation_about
from chekhov.viewer.draw import (
    PATH_RGB,
    SEED_RGB,
    RobotDrawing,
    SphereDrawing,
    camera_for,
    draw_draggable,
    draw_roadmap,
    draw_scene,
    draw_trace,
    pose_of,
)
from chekhov.viewer.meshes import RobotMeshes, se3_to_wxyz_xyz
from chekhov.viewer.planning import (
    PLANNER_NAMES,
    ROADMAP_TRAJOPT,
    PlannerPool,
    PlanView,
    polyline_segments,
)
from chekhov.world import World

Array = NDArray[np.float64]

OBSTACLE_NAME = "person_arm"
OBSTACLE_SHAPE = Shape("cylinder", (0.06, 0.5))  # a forearm: 6 cm radius, 50 cm long


class ViewerError(ChekhovError):
    """The viewer cannot start (port taken, bad address, missing package)."""


def check_port_free(host: str, port: int) -> None:
    """Raise ViewerError when nothing can listen on host:port (taken, or a bad address)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError as e:
            if e.errno == errno.EADDRINUSE:
                raise ViewerError(f"port {port} on {host} is already in use (another viewer?); "
                                  "choose another with --port") from e
            raise ViewerError(f"cannot listen on {host}:{port}: {e.strerror or e}") from e


def default_obstacle_pose(world: World) -> Array:
    """T_world_obj of the draggable obstacle: in front of the robot, to its right, lying
    along the robot's forward axis (a person's forearm reaching in), out of the way."""
    Tb = world.robot.T_world_base
    T = make_transform((0.65, -0.45, 0.15), rotation_about((0.0, 1.0, 0.0), np.pi / 2))
    return np.asarray(Tb @ T, dtype=float)


def serve_until_stopped(stop: threading.Event, close: Callable[[], None]) -> None:
    """Block until ``stop`` is set or Ctrl-C, then ``close()``: a viewer's serve_forever."""
    try:
        while not stop.wait(0.5):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        close()


def start_server(world: World, *, host: str, port: int) -> viser.ViserServer:
    """A viser server on host:port (0: any free port) with its camera on ``world``'s robot;
    ViewerError when it lost the port to another process."""
    server = viser.ViserServer(host=host, port=port, verbose=False)
    if port != 0 and server.get_port() != port:  # lost a race for the port
        server.stop()
        raise ViewerError(f"port {port} on {host} is already in use; choose another "
                          "with --port")
    eye, look = camera_for(world)
    server.initial_camera.position = tuple(eye)
    server.initial_camera.look_at = tuple(look)
    return server


class Viewer:
    """A viser server showing one world, with planning and live replanning.

    Args:
        world: the planning world; the viewer adds one dynamic obstacle to it
            (``obstacle_name``) unless ``obstacle`` is None.
        roadmap: the roadmap for Roadmap + TrajOpt (and the drawn graph); None: the cached
            one (``load_or_build_roadmap``).
        cases: start / goal cases to pick from; None: 20 cached cases (seed 0).
        host, port: where to listen (localhost by default); a taken port raises ViewerError.
        obstacle: shape of the draggable dynamic obstacle (default a forearm cylinder).
        show_spheres, show_roadmap, show_edges: initial state of those layers (the collision
            spheres, the roadmap's nodes, its edges; toggled in the GUI).
        plan_on_start: plan case 0 with Roadmap + TrajOpt before returning.

    Attributes:
        handles: scene and GUI handles by name (e.g. ``"/plan/path"``, ``"gui/planner"``).
        view: the plan shown (PlanView) or None. replan_times_s: every live replan's time.
    """

    def __init__(self, world: World, roadmap: Roadmap | None = None,
                 cases: CaseSet | None = None, *, host: str = "127.0.0.1", port: int = 8080,
                 obstacle: Shape | None = OBSTACLE_SHAPE, obstacle_name: str = OBSTACLE_NAME,
                 obstacle_pose: Array | None = None, show_spheres: bool = False,
                 show_roadmap: bool = True, show_edges: bool = False,
                 plan_on_start: bool = True) -> None:
        if port != 0:
            check_port_free(host, port)
        if roadmap is None:
            from chekhov.roadmap.io import load_or_build_roadmap
            roadmap = load_or_build_roadmap(world)
        self.world = world
        self.roadmap = roadmap
        self.cases = cases if cases is not None else cached_cases(world, 20)
        if len(self.cases) == 0:
            raise ViewerError("no cases to show")
        self.cases.check_world(world)
        self.planners = PlannerPool(world, roadmap)
        self._lock = threading.RLock()        # world changes and planning
        self._display = threading.Lock()      # robot pose updates
        self._dirty = threading.Event()       # an obstacle moved: replan
        self._stop = threading.Event()
        self.view: PlanView | None = None
        self.replan_times_s: list[float] = []
        self.case_index = 0
        self.q_start = self.cases.q_start[0].copy()
        self.goal = self.cases.goal(0)
        self.handles: dict[str, Any] = {}

        self._start_server(host, port)
        self._draw_world(show_spheres, show_roadmap, show_edges)
        self.obstacles: dict[str, viser.TransformControlsHandle] = {}
        self.obstacle_name = obstacle_name if obstacle is not None else None
        self._add_obstacles(obstacle, obstacle_name, obstacle_pose)
        self.handles["/plan/seed"] = draw_trace(self.server, "/plan/seed", None, SEED_RGB, 3.0)
        self.handles["/plan/path"] = draw_trace(self.server, "/plan/path", None, PATH_RGB, 5.0)
        self._build_gui(show_spheres, show_roadmap, show_edges)
        self._start_threads()
        if plan_on_start:
            self.select_case(0, plan=True)

    def _start_server(self, host: str, port: int) -> None:
        """The viser server on host:port (0: any free port), its camera on the robot."""
        self.server = start_server(self.world, host=host, port=port)
        self.host, self.port = host, int(self.server.get_port())

    def _draw_world(self, show_spheres: bool, show_roadmap: bool, show_edges: bool) -> None:
        """The scene, the robot at the start, its spheres, the roadmap and the markers."""
        world = self.world
        self.handles.update(draw_scene(self.server, world))
        self.robot_meshes = RobotMeshes(world.robot)
        self.robot = RobotDrawing(self.server, self.robot_meshes, self.q_start)
        self.spheres = SphereDrawing(self.server, world, self.q_start, visible=show_spheres)
        self.handles["/roadmap/nodes"], self.handles["/roadmap/edges"] = draw_roadmap(
            self.server, self.roadmap, show_roadmap, show_edges)
        self._add_markers()

    def _add_obstacles(self, obstacle: Shape | None, name: str, pose: Array | None) -> None:
        """A gizmo on each of the scene's dynamic objects, and the draggable obstacle
        ``obstacle`` (added to the world at ``pose``, T_world_obj, default beside the robot)."""
        for o in self.world.scene.dynamic_objects:
            self._add_obstacle_gizmo(o, o.T_world_obj())
        if obstacle is not None:
            T = default_obstacle_pose(self.world) if pose is None else pose
            self.world.add_obstacle(name, obstacle, T)
            self._add_obstacle_gizmo(SceneObject(name, obstacle, Pose(), "person",
                                                 dynamic=True), T)

    def _start_threads(self) -> None:
        """The replanning worker and the animation loop (daemon threads)."""
        self._worker = threading.Thread(target=self._replan_loop, daemon=True,
                                        name="chekhov-replan")
        self._worker.start()
        self._animator = threading.Thread(target=self._animate_loop, daemon=True,
                                          name="chekhov-animate")
        self._animator.start()

    # --- Python API ---------------------------------------------------------------------
    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    def select_case(self, i: int, plan: bool = True) -> PlanView | None:
        """Make case i the start and goal (the goal gizmo moves there); plan it if asked,
        with the planner chosen in the GUI."""
        if not 0 <= i < len(self.cases):
            raise ViewerError(f"case {i} out of range: {len(self.cases)} cases")
        self.case_index = i
        self.q_start = self.cases.q_start[i].copy()
        self.set_goal(self.cases.T_world_ee_goal[i], plan=False)
        start = self.handles["/case/start"]
        start.wxyz, start.position = se3_to_wxyz_xyz(self.cases.T_world_ee_start[i])
        self._show_q(self.q_start)
        return self.replan(self.handles["gui/planner"].value) if plan else None

    def set_goal(self, T_world_ee: Array, plan: bool = False) -> PlanView | None:
        """A new goal pose (4, 4); the goal gizmo follows."""
        T = np.asarray(T_world_ee, dtype=float)
        self.goal = Goal.pose(T)
        g = self.handles["/goal"]
        g.wxyz, g.position = se3_to_wxyz_xyz(T)
        return self.replan(self.handles["gui/planner"].value) if plan else None

    def move_obstacle(self, T_world_obj: Array, name: str | None = None) -> None:
        """Move a dynamic obstacle (default: the viewer's) in the world and in the browser.
        Does not replan; call :meth:`replan`."""
        name = name or self.obstacle_name
        if name is None or name not in self.obstacles:
            raise ViewerError(f"no dynamic obstacle '{name}'; have {list(self.obstacles)}")
        with self._lock:
            self.world.move_obstacle(name, np.asarray(T_world_obj, dtype=float))
        gizmo = self.obstacles[name]
        gizmo.wxyz, gizmo.position = se3_to_wxyz_xyz(np.asarray(T_world_obj, dtype=float))

    def replan(self, planner: str = ROADMAP_TRAJOPT) -> PlanView:
        """Plan from the current start to the current goal against the world's current
        obstacles, show the result, and return it."""
        with self._lock:
            p = self.planners.get(planner)
            result = p.plan(self.q_start, self.goal, time_limit_s=5.0)
            view = PlanView.of(self.world, planner, result)
        self.show_plan(view)
        return view

    def show_plan(self, view: PlanView) -> None:
        """Show a plan: seed and trajectory traces, the summary, the animation from t = 0."""
        self.view = view
        for name, pts in (("/plan/seed", view.ee_seed), ("/plan/path", view.ee_path)):
            h = self.handles[name]
            if pts is not None:
                h.points = polyline_segments(pts).astype(np.float32)
            h.visible = pts is not None and (name != "/plan/seed"
                                             or self.handles["gui/show_seed"].value)
        self.handles["gui/result"].content = view.summary_markdown()
        self._phase = 0.0
        self.handles["gui/t"].value = 0.0
        self._show_q(self.q_start if view.path is None else view.path[0])

    def shown_path(self) -> Array | None:
        """End-effector trace (T, 3) of the trajectory drawn in the browser, or None."""
        h = self.handles["/plan/path"]
        if not h.visible:
            return None
        seg = np.asarray(h.points, dtype=float)
        return np.vstack([seg[:, 0], seg[-1:, 1]])

    def serve_forever(self) -> None:
        """Block until Ctrl-C (or :meth:`close` from another thread)."""
        serve_until_stopped(self._stop, self.close)

    def close(self) -> None:
        if self._stop.is_set():
            return
        self._stop.set()
        self._dirty.set()
        self.server.stop()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- scene pieces -------------------------------------------------------------------
    def _add_markers(self) -> None:
        sc = self.server.scene
        self.handles["/case/start"] = sc.add_frame("/case/start", axes_length=0.08,
                                                   axes_radius=0.006, origin_radius=0.015,
                                                   origin_color=(40, 200, 40))
        gizmo = sc.add_transform_controls("/goal", scale=0.2)
        self.handles["/goal"] = gizmo
        self.handles["/goal/frame"] = sc.add_frame("/goal/frame", axes_length=0.08,
                                                   axes_radius=0.006, origin_radius=0.015,
                                                   origin_color=(220, 40, 40))

        def on_goal(event: Any) -> None:
            if event.phase != "end":
                return
            T = pose_of(gizmo)
            self.goal = Goal.pose(T)
            self.request_replan(plan_goal=True)

        gizmo.on_update(on_goal)

    def _add_obstacle_gizmo(self, obj: SceneObject, T: Array) -> None:
        name = obj.name

        def on_move(T_world_obj: Array) -> None:
            with self._lock:
                self.world.move_obstacle(name, T_world_obj)
            if self.handles["gui/live"].value:
                self.request_replan()

        gizmo, mesh = draw_draggable(self.server, obj, T, on_move)
        self.handles[f"/obstacles/{name}/mesh"] = mesh
        self.handles[f"/obstacles/{name}"] = gizmo
        self.obstacles[name] = gizmo

    # --- GUI ----------------------------------------------------------------------------
    def _build_gui(self, show_spheres: bool, show_roadmap: bool, show_edges: bool) -> None:
        """The GUI panel (``handles["gui/…"]``) and what its controls do."""
        self._add_gui_controls(show_spheres, show_roadmap, show_edges)
        self._wire_gui_callbacks()

    def _add_gui_controls(self, show_spheres: bool, show_roadmap: bool, show_edges: bool
                          ) -> None:
        """The panel's folders: Plan, Playback, Dynamic obstacle, Show, Result."""
        gui = self.server.gui
        h = self.handles
        rm = self.roadmap
        gui.add_markdown(f"**chekhov** · `{self.world.scene.name}` · roadmap {rm.n_nodes} "
                         f"nodes / {rm.n_edges} edges · {len(self.cases)} cases")
        with gui.add_folder("Plan"):
            h["gui/planner"] = gui.add_dropdown("planner", PLANNER_NAMES,
                                                initial_value=ROADMAP_TRAJOPT)
            h["gui/case"] = gui.add_dropdown("case", tuple(str(i) for i in
                                                           range(len(self.cases))))
            h["gui/plan"] = gui.add_button("Plan")
            gui.add_markdown("Pick a case, or drag the goal gizmo (red) to plan to a new "
                             "end-effector pose.")
        with gui.add_folder("Playback"):
            h["gui/t"] = gui.add_slider("time", min=0.0, max=1.0, step=0.002,
                                        initial_value=0.0)
            h["gui/play"] = gui.add_checkbox("play", initial_value=True)
        with gui.add_folder("Dynamic obstacle"):
            h["gui/live"] = gui.add_checkbox("replan on move", initial_value=True)
            h["gui/replan_time"] = gui.add_markdown("Drag the red-orange obstacle: Roadmap + "
                                                    "TrajOpt replans on every move.")
        with gui.add_folder("Show"):
            h["gui/show_roadmap"] = gui.add_checkbox("roadmap nodes (end effector)",
                                                     initial_value=show_roadmap)
            h["gui/show_edges"] = gui.add_checkbox("roadmap edges", initial_value=show_edges)
            h["gui/show_seed"] = gui.add_checkbox("seed trace", initial_value=True)
            h["gui/show_spheres"] = gui.add_checkbox("collision spheres",
                                                     initial_value=show_spheres)
        with gui.add_folder("Result"):
            h["gui/result"] = gui.add_markdown("(no plan yet)")

    def _wire_gui_callbacks(self) -> None:
        """Case and Plan replan; the time slider poses the robot; Show toggles layers."""
        h = self.handles

        @h["gui/case"].on_update
        def _(_: Any) -> None:
            self.select_case(int(h["gui/case"].value), plan=False)
            self.request_replan(plan_goal=True)

        @h["gui/plan"].on_click
        def _(_: Any) -> None:
            self.request_replan(plan_goal=True)

        @h["gui/t"].on_update
        def _(_: Any) -> None:
            q = None if self.view is None else self.view.configuration_at(
                float(h["gui/t"].value))
            if q is not None:
                self._show_q(q)

        @h["gui/show_roadmap"].on_update
        def _(_: Any) -> None:
            h["/roadmap/nodes"].visible = bool(h["gui/show_roadmap"].value)

        @h["gui/show_edges"].on_update
        def _(_: Any) -> None:
            h["/roadmap/edges"].visible = bool(h["gui/show_edges"].value)

        @h["gui/show_seed"].on_update
        def _(_: Any) -> None:
            h["/plan/seed"].visible = bool(h["gui/show_seed"].value) and (
                self.view is not None and self.view.ee_seed is not None)

        @h["gui/show_spheres"].on_update
        def _(_: Any) -> None:
            self.spheres.set_visible(bool(h["gui/show_spheres"].value))

    # --- background work ----------------------------------------------------------------
    def request_replan(self, plan_goal: bool = False) -> None:
        """Ask the background worker to plan (returns at once): with ``plan_goal`` the GUI's
        planner to the current goal, else a live Roadmap + TrajOpt replan (what a gizmo move
        does); requests made while it plans are merged into one."""
        if plan_goal:
            self._goal_pending = True
        self._dirty.set()

    _goal_pending = False

    def _replan_loop(self) -> None:
        """Coalesces requests: while a plan runs, further moves only mark the world dirty,
        and the next plan sees the latest obstacle poses."""
        while not self._stop.is_set():
            self._dirty.wait()
            self._dirty.clear()
            if self._stop.is_set():
                return
            goal_plan, self._goal_pending = self._goal_pending, False
            try:
                if goal_plan:
                    self.replan(self.handles["gui/planner"].value)
                else:
                    view = self.replan(ROADMAP_TRAJOPT)
                    self.replan_times_s.append(view.result.time_s)
                    self.handles["gui/replan_time"].content = (
                        f"last replan: **{1e3 * view.result.time_s:.0f} ms** "
                        f"({view.result.status}), {len(self.replan_times_s)} so far")
            except ChekhovError as e:
                self.handles["gui/result"].content = f"planning failed: {e}"

    _phase = 0.0

    def _animate_loop(self, period_s: float = 3.0, fps: float = 25.0) -> None:
        """While "play" is on, run the time slider 0 → 1 — in the timed trajectory's own
        duration (real time), else in period_s —, hold, and loop."""
        while not self._stop.wait(1.0 / fps):
            if not self.handles["gui/play"].value or self.view is None \
                    or self.view.path is None:
                continue
            timed = self.view.timed
            period = timed.duration if timed is not None and timed.duration > 0 else period_s
            self._phase += 1.0 / (period * fps)
            if self._phase > 1.0 + 0.4:
                self._phase = 0.0
            self.handles["gui/t"].value = round(min(self._phase, 1.0), 3)

    def _show_q(self, q: Array) -> None:
        with self._display:
            self.robot.show(q)
            self.spheres.show(q)
