"""Geometry: the system plane (pyproj stereographic), radar polar ↔ plane, and the kinematic closed forms."""
