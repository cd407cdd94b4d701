"""Stage analysis: Trajectory / SweepResult -> numbers, then figures."""
