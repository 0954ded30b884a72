"""The simulated world, boat and instruments, down to the bytes on virtual serial ports."""
