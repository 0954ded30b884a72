"""Decoders: NMEA 0183, MAVLink and the bridge's frames to SI values; bad input counted, never raised."""
