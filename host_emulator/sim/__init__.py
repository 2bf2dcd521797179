"""Simulation: truth trajectories of a car, a BMI055-class IMU and a GNSS receiver (float64).

    trajectory.SCENARIOS[name](duration_s=None, seed=0) -> Truth   200 Hz truth
    imu.simulate(truth, ImuModel(), seed) -> ImuData                 register counts + SI
    gnss.simulate(truth, GnssModel(), seed, outages) -> GnssData     fixes, PPS edges

Conventions (those of firmware/lib/rot.py and geo.py):
- Navigation frame: East-North-Up tangent plane at an integer origin (lat/lon in 1e-7 deg,
  ellipsoidal height), fixed to the Earth; default origin Xi'an, 34.26 N 108.94 E, 400 m.
- Body frame: x right, y forward, z up. q_bn = [w, x, y, z] rotates body to nav, w >= 0.
  ypr = [yaw, pitch, roll] rad with C_n^b = R_y(roll) R_x(pitch) R_z(yaw); yaw is positive
  counter-clockwise from north, so compass heading = -yaw (GNSS course is clockwise).
- Time: t = k * 5 ms; every IMU sample is the instantaneous value at t_k; GNSS epochs fall on
  whole multiples of 1/rate and t = 0 is the top of a second.
- SI units inside (m, s, rad); degrees, 1e-7 deg and register counts only where named.
- Everything is deterministic in its seed; the trajectory, the IMU and the receiver draw from
  separate streams, so changing one model leaves the others' noise unchanged.
"""
