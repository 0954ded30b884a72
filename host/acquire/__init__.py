"""Acquisition: reader threads stamp the instruments' bytes on arrival; the daemon runs them into the pipeline."""
