"""Simulation: the rotating-radar simulator, real recorded flights and the built-in scenarios."""
