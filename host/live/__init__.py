"""The live view ashore: every logged topic on a Foxglove WebSocket server, health and alerts, and maps
of current, wind and depth that grow during the survey (docs/LIVE.md).

Nothing here is imported by `forcemap run` without `--live`; only `server` imports foxglove-sdk.
"""
