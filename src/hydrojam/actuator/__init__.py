"""The actuator: design (TOML), geometry, model (bodies, materials, clamp, contact), stimulus path,
simulation, metrics, output files and figures."""
