"""Roadmap + TrajOpt's settings: :class:`RoadmapTrajOptConfig`, and the TrajOpt settings it
starts from (:func:`roadmap_trajopt_config`), each figure with what it was measured to do."""

from __future__ import annotations

from dataclasses import dataclass, field

from chekhov._config_checks import int_at_least
from chekhov.errors import ChekhovError
from chekhov.roadmap.seeder import SeederConfig
from chekhov.trajopt.config import TrajOptConfig

SEED_STEP_RAD = 0.32
"""rad: Roadmap + TrajOpt resamples its seed so that adjacent waypoints are at most this far
apart (twice the paper's 0.16; the answer is still certified at 0.16 rad and 100 substeps,
and TrajOpt's swept-sphere terms cover the motion between waypoints). Half the waypoints:
shorter answers, sooner. Measured (60 cases a scene, seed 0, 0.16 against 0.32, one run each,
2026-11-28): task cases, mean length -1 to -8% in every scene (shelf_boxes 4.42 → 4.07 rad,
kitchen 5.25 → 4.90), mean plan time -3 to -16% (shelf 50 → 42 ms), mean timed duration
-2 to -12%; random cases, length -0.3 to -2%, mean time -5 to -15%; 0.48 shorter still but
no faster. On a UR5 (30 tabletop_pole tasks, two runs): length 3.22 → 3.16 rad, mean time
22 → 24 ms; every answer exactly free at 400 substeps."""


SEGMENT_TERMS = 4
"""Swept-sphere terms kept per segment in Roadmap + TrajOpt's TrajOpt (the defaults': 8). Its
seeds are collision-free and hug few obstacles at once, so the four closest pairs of a
segment carry its constraint; a smaller QP solves faster, and every answer is validated
exactly anyway. Measured (60 cases a scene, seed 0, each variant with its own world,
alternating twice, 2026-11-30): task cases, mean plan time kitchen 20.3 → 18.7 ms, shelf_boxes
16.3 → 15.2, panda_cage 13.4 → 12.2, panda_table_shelf 10.4 → 9.7, tabletop_container 10.7 →
11.1; mean length −1.9% to +0.5%; random cases (kitchen, panda_cage) within 2%; no failure."""


MIN_APPROX_IMPROVE_FRAC = 0.02
"""Roadmap + TrajOpt's TrajOpt stops at a penalty level once a step's model promises less than
this share of the merit (the defaults': 0.01). From a certified seed, its first accepted step
gives two thirds of the length it gains and three steps 93%, 1.4 ms a step (40 kitchen task
runs traced); the last steps before 0.01 is reached gain ~1% of the path's length. Measured
(60 cases a scene, seed 0, both variants in one process, alternating per case, 2026-12-01):
task cases, mean plan time kitchen 18.5 → 16.3 ms (median 16.9 → 14.1), shelf_boxes 15.3 →
12.8, panda_cage 11.4 → 10.5, tabletop_container 10.9 → 9.4, panda_table_shelf 9.6 → 8.5;
random cases kitchen 10.7 → 9.2, tabletop_pole 7.5 → 6.9; mean length +0.1 to +0.9%; no
failure. On arms it was not chosen on (40 tabletop_pole task cases): UR5 8.9 → 7.9 ms, xArm7
10.5 → 9.3, the same mean length within 0.1%."""


VALIDATE_EACH_LEVEL = True
"""Roadmap + TrajOpt's TrajOpt validates its trajectory at the end of each penalty level where
only the sphere model's clearance is unmet, and ends there when the exact check passes
(``TrajOptConfig.validate_each_level``). On a TIAGo (its spheres overlap its torso and hand
where the links do not touch: no trajectory meets the sphere clearance) every run raised the
penalty four times before the exact validation accepted it. Measured (both in one process,
alternating per case, 2026-12-02): TIAGo, 40 random cases in tabletop_pole, median 29.9 →
23.6 ms, mean 28.0 → 22.6, optimisation 12.5 → 7.9 ms a case, final answers from it 5 → 8;
kitchen task cases (50) mean 14.6 → 13.9 ms; panda_cage tasks, shelf_boxes tasks and random,
a UR5's random cases unchanged within 2%; mean lengths within 0.2%."""


def roadmap_trajopt_config() -> TrajOptConfig:
    """TrajOpt's settings in Roadmap + TrajOpt: the defaults, its seed resampled at
    :data:`SEED_STEP_RAD`, :data:`SEGMENT_TERMS` swept terms per segment, each penalty level
    ended at :data:`MIN_APPROX_IMPROVE_FRAC`, runs that stall ended after two penalty levels
    (``TrajOptConfig.stall_levels``: its straight-line tries through a cabinet wall ran to
    their 40 ms budget while a certified answer waited), a level short of the sphere
    clearance only validated at once (:data:`VALIDATE_EACH_LEVEL`)."""
    return TrajOptConfig(max_step_rad=SEED_STEP_RAD, terms_per_segment=SEGMENT_TERMS,
                         min_approx_improve_frac=MIN_APPROX_IMPROVE_FRAC, stall_levels=2,
                         validate_each_level=VALIDATE_EACH_LEVEL)


@dataclass(frozen=True)
class RoadmapTrajOptConfig:
    """Roadmap + TrajOpt's settings (see :class:`RoadmapTrajOpt` for what each does).

    Attributes:
        trajopt: TrajOpt's settings (:func:`roadmap_trajopt_config`: the seed resampled at
            :data:`SEED_STEP_RAD`). seeder: the roadmap queries' settings.
        shortcut: shortcut each roadmap route greedily before TrajOpt.
        shortcut_clearance_m: m, the clearance the shortcuts (greedy and between any two
            points) keep: their motions are checked with every link's geometry at least
            this far from everything (``FastChecker.clearance_world``). A shortcut that
            grazes the sphere model's surface passes near contact along its length, where the
            certification's screen (its margins: 0.3-1.5 mm) alarms and coal decides sample
            by sample — on a robot of meshes (the Panda), 50-110 ms for some answers.
            Measured on 100 task cases a scene, 0 against 1 mm in one process: offers'
            certification 11.1 → 5.5 ms a case on average (p95 62 → 20) and plan() mean
            41 → 35 ms on panda_cage (2 mm: 5.0 ms; on panda_table_shelf 11.0 → 4.1 ms and
            37 → 32 ms), the same mean path length within 0.7% in shelf_boxes and kitchen,
            whose Baxter links are primitives that coal decides fast (offers 2-3 ms a case
            either way).
        straight_line_first: TrajOpt from a straight line first, for at most
            ``straight_line_time_s`` s (False: the paper's planner, every query from the
            roadmap).
        straight_line_fallback: when the roadmap cannot connect or dynamic obstacles cut every
            route, TrajOpt from a straight line for at most ``fallback_time_s`` s.
        goal_routes: routes through the roadmap (one per goal IK solution) shortcut and
            compared; TrajOpt starts from the shortest. Six until 2026-12-01; three since:
            the other three's IK solutions, connections and shortcuts took a quarter of a
            task plan and seldom gave TrajOpt a better seed. Measured (60 cases a scene,
            seed 0, both in one process, alternating per case): task cases, mean plan time
            kitchen 18.0 → 15.8 ms, shelf_boxes 15.6 → 13.2, panda_cage 12.2 → 10.7,
            tabletop_pole 11.7 → 9.6, tabletop_container 10.4 → 8.9, panda_table_shelf 9.8 →
            8.2; random cases kitchen 10.9 → 9.3, panda_cage 7.1 → 6.5; mean length -2% to
            +1% except tabletop_container's tasks (+2.5%); on arms it was not chosen on (40
            tabletop_pole task cases) UR5 8.8 → 7.6 ms, xArm7 11.3 → 9.6, length 0% and -2%.
        repair: when the roadmap could not connect or dynamic obstacles cut every route,
            search with a bidirectional tree that connects into the roadmap
            (:mod:`chekhov.roadmap.repair`) until the time limit, before any straight-line
            fallback; its path is shortcut and optimised like a roadmap seed.
        repair_reserve: fraction of the time left (at most 50 ms) kept back from the repair
            search for shortcutting and the exact check of its path.
        straight_line_ratio, straight_line_max_blocked: after the first answer, TrajOpt from
            a straight line is tried only when that answer is longer than
            ``straight_line_ratio`` times the straight line (in joint space) and at most
            ``straight_line_max_blocked`` of 64 configurations along the line collide — a
            per-query decision from what is cheap to know. Measured (shelf and kitchen, 40
            cases each): the line's TrajOpt won 3 of 4 tries with ≤ 18% blocked and 0 of 24
            with ≥ 23% (each loss ~40 ms). The ratio is the simplified seed's (the line is
            decided after the routes and the shortcuts between any two points); 1.2 until
            2026-12-01, 1.5 since: from a seed within 1.5 times the line, TrajOpt from the seed
            ends as short, and the line's tries that lost cost 20-30 ms each. Measured (80
            cases a scene, seed 0, both in one process, alternating per case): task cases,
            mean plan time kitchen 16.4 → 14.6 ms (p95 30 → 26), shelf_boxes 13.7 → 12.1,
            panda_cage 10.4 → 9.2, tabletop_pole 10.2 → 8.8, tabletop_container 9.3 → 8.1,
            panda_table_shelf 8.8 → 7.8; random cases kitchen 10.7 → 9.2, shelf_boxes 8.5 →
            7.7 (p95 20 → 14); mean length within +0.6%; on arms it was not chosen on (40
            tabletop_pole random cases) UR5 9.8 → 8.4 ms, xArm7 6.2 → 5.9, the same lengths.
        simplify_rounds: rounds of shortcuts between any two points of the seed (batches of
            16 random pairs, the best free one spliced in; 0: none) before TrajOpt.
        improve_time_s: s after the first certified answer by which the improvements (more
            routes, partial shortcuts, straight-line TrajOpt, TrajOpt from the seed) end:
            each is given what is left of it (and never more than the time limit). An
            improvement's certification must end ``improve_time_s`` after that, else it is
            dropped and the answer so far stands.
        min_length_gain: TrajOpt from the seed towards a configuration (the goal's, or the
            seed's own end) is skipped when the seed is at most this fraction longer than the
            straight line to it: no path there is shorter than the line, so no more could be
            gained (``info["trajopt_skipped"]`` says so). Measured on 40 panda_table_shelf
            task cases: 10 such seeds, 10-28 ms of TrajOpt each, none shortened; 12 and 15
            of 40 other cases skipped in panda_table_shelf and panda_cage.
        abandon_ratio: TrajOpt from the seed stops ("abandoned") when, after its second
            accepted step, its trajectory is more than this factor longer than the answer so
            far (inf: never). Its iterates then pushed the path off the obstacles the seed
            hugs and it would not come back. Traced step by step with the bound off: 42 runs
            over it at their second step (40 task or random cases a scene, seeds 1-2; 39 on
            the Panda), none ended shorter than the answer, each taking up to the whole
            ``improve_time_s``; none of the 132 runs that beat the answer was over it.
        improve_time_scale: the improvements are given at least this many times what the
            first answer took (when that is more than ``improve_time_s``): on an arm whose
            checks are slow the same work takes longer — a UR10 without its SRDF (43k checks
            a second) spent all of 0.1 s in the partial shortcuts, TrajOpt never ran, and its
            paths were 50% longer (12 queries: 18.7 rad against 12.4 with 1 s, in about the
            same time). Baxter's and the Panda's first answers (1-3 ms) leave the budget at
            ``improve_time_s``.
    """

    trajopt: TrajOptConfig = field(default_factory=roadmap_trajopt_config)
    seeder: SeederConfig = field(default_factory=SeederConfig)
    shortcut: bool = True
    shortcut_clearance_m: float = 0.001
    straight_line_first: bool = True
    straight_line_time_s: float = 0.04
    straight_line_fallback: bool = True
    fallback_time_s: float = 0.25
    goal_routes: int = 3
    repair: bool = True
    repair_reserve: float = 0.2
    straight_line_ratio: float = 1.5
    straight_line_max_blocked: float = 0.2
    improve_time_s: float = 0.1
    improve_time_scale: float = 4.0
    simplify_rounds: int = 8
    min_length_gain: float = 0.01
    abandon_ratio: float = 1.05

    def __post_init__(self) -> None:
        for name, unit in (("straight_line_time_s", " of s"), ("fallback_time_s", " of s"),
                           ("improve_time_s", " of s"), ("improve_time_scale", ""),
                           ("straight_line_ratio", ""),
                           ("shortcut_clearance_m", " of m"),
                           ("straight_line_max_blocked", ""), ("min_length_gain", "")):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and v >= 0):
                raise ChekhovError(f"RoadmapTrajOptConfig.{name}: must be a number{unit} >= 0, "
                                   f"got {v!r}")
        r = self.abandon_ratio
        if not (isinstance(r, int | float) and r >= 1.0):
            raise ChekhovError(f"RoadmapTrajOptConfig.abandon_ratio: must be a number >= 1 (a "
                               f"run is abandoned only when longer than the answer so far), "
                               f"got {r!r}")
        int_at_least("RoadmapTrajOptConfig", "goal_routes", self.goal_routes, 1)
