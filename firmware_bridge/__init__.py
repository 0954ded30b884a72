"""MicroPython bridge firmware: pulse counters, vane ADC and the framed USB-CDC stream."""
