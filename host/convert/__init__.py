"""Logs in and out: existing logs (NMEA, tlog, DataFlash) through the pipeline; MCAP to tables and tracks."""
