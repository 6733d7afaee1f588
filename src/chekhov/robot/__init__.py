"""Robot models: kinematics, IK, sphere models."""
