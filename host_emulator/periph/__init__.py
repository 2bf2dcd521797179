"""Emulated peripherals: what the firmware's drivers talk to on the desktop."""
