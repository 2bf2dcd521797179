"""The board's UsartGPU screen on the PC: the strict reader of what the firmware sends it
(usartgpu.py)."""
