"""The survey report: one HTML file composed from the workbench and the plan (only the CLI imports it)."""
