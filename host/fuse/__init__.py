"""Fusion: device clocks, the boat's state and compensation turn decoded values into sample rows."""
