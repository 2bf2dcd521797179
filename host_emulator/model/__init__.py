"""NumPy float32 model of the firmware's arithmetic, vectorised, mirroring the firmware's
operation order."""
