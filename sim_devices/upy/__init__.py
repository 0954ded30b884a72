"""Harness that runs the bridge firmware under the real unix-port ``micropython`` binary."""
