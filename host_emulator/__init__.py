"""Desktop side of the product: the float32 model of the board, and (later) simulation,
emulated peripherals, runners and evaluation around the unmodified firmware."""
