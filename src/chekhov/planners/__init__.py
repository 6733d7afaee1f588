"""Planners: one interface (``Planner.plan(q_start, goal, time_limit_s) -> PlanResult``)."""
