"""The boat as the planner and the simulator both describe it: geodesy, hull and autopilot equations,
mission files (QGC WPL 110, mission TOML) and the scenarios missions are laid out in."""
