"""What the daemon logs: one typed record per topic, written to and read from crash-safe MCAP."""
