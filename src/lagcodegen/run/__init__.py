"""Stage run: CompiledSystem -> Trajectory / SweepResult (the stepping loops run in C)."""
