"""Depth as a hydrographer reads it: the surface most soundings support, and the water level under every depth."""
