"""Controllers that steer the swimmer: the paper's rule-based turn planner and PPO agents."""
