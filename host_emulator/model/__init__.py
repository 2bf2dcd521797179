"""The NumPy float32 model of the firmware: an independent implementation of its arithmetic,
vectorised where the firmware loops, that repeats every float32 operation in the firmware's
order, so the two agree bit for bit (the parity oracle; docs/requirements.md, float32 contract).

One file per firmware module it mirrors: fmath.py, mat.py, rot.py, geo.py (firmware/lib), ins.py,
eskf.py, nav.py, nav_align.py, nav_aid.py (the navigator), app.py (firmware/app.py: the output
stream of a whole run); f32ops.py holds the float32 helpers several of them share. Constants
are the firmware modules' own objects, never retyped.
"""
