"""TrajOpt: sequential convex trajectory optimisation (Schulman et al.) with signed-distance
collision terms from the fast checker, pose goals, joint / velocity / acceleration / torque
limits. ``build_trajopt`` returns an inspectable problem, ``solve_trajopt`` solves it."""
