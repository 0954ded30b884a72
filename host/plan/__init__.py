"""`forcemap plan`: missions predicted through the mapped current and wind, and adjusted to hold their lines.

maps (the survey's fits as gridded fields), boat_model, predict (the track), metrics (lines held),
adjust (the adjusted mission), planner (the whole plan and its report), mission_io (files), upload
(MAVLink), workspace_io and report_section (the report), closed_loop (judged against the simulator).
"""
