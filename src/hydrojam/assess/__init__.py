"""Assessing an actuator: stiffness, blocked force, confinement and the vacuum-jamming baseline (issue 15, docs/assess.md)."""
