"""A recorded drive as the replay needs it, whatever file layout it came in.

Conventions, stated once for `host_emulator.replay`:
- Time: GPST seconds since the GPS epoch 1980-01-06 00:00:00, float64 (`gpst()` converts a
  calendar date; GPS week seconds are `t - week * 604800`).
- Vehicle body frame: forward-right-down (FRD), navigation frame north-east-down (NED), as
  KF-GINS and RTKLIB use; attitude as roll, pitch, yaw in degrees (yaw clockwise from north).
  The firmware's own frames (right-forward-up, ENU) appear only in `to_stimulus.py`.
- IMU sample i: the mean angular rate and specific force over (t[i-1], t[i]] in the sensor's
  own axes (an increment divided by its interval), rad/s and m/s^2.
- Mounting: `mount_rpy_deg` = [roll, pitch, yaw] such that the sensor-to-body rotation is
  C_s^b = (Rz(yaw) Ry(pitch) Rx(roll))^T, x_body = C_s^b x_sensor (the form in which the
  drive_0708 publisher states [180, -6.79, 185.35]; checked against the data in the tests:
  at rest the body specific force is (0, 0, -g) to within the accelerometer bias).
- Lever arm: from the IMU to the GNSS antenna, body FRD axes, m.
"""

import datetime
from dataclasses import dataclass, field

import numpy as np

GPS_EPOCH = datetime.datetime(1980, 1, 6)
# Swaps the first two axes and flips the third: FRD <-> the firmware's RFU body axes, and
# NED <-> ENU (its own inverse).
SWAP_FRD_RFU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
WEEK_S = 604800.0


def gpst(when):
    """GPST seconds since the GPS epoch of a naive datetime read as GPST."""
    return (when - GPS_EPOCH).total_seconds()


def gpst_datetime(t_s):
    """The naive datetime (GPST) of GPST seconds."""
    return GPS_EPOCH + datetime.timedelta(seconds=float(t_s))


def mount_matrix(rpy_deg):
    """C_s^b (3x3, sensor axes -> body FRD) of `mount_rpy_deg` (module docstring)."""
    r, p, y = np.radians(np.asarray(rpy_deg, float))
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return (rz @ ry @ rx).T


@dataclass(eq=False)
class Imu:
    t_s: np.ndarray  # (N,) GPST s, end of each sample's interval, increasing
    gyro_rad_s: np.ndarray  # (N, 3) sensor axes
    accel_m_s2: np.ndarray  # (N, 3) sensor axes

    def __len__(self):
        return self.t_s.size


@dataclass(eq=False)
class Positions:
    """Positions over time: a reference trajectory (truth) or GNSS fixes."""

    t_s: np.ndarray  # (M,) GPST s, increasing
    lat_deg: np.ndarray  # (M,)
    lon_deg: np.ndarray  # (M,)
    h_m: np.ndarray  # (M,) ellipsoidal height
    sigma_ned_m: np.ndarray | None = None  # (M, 3) 1-sigma north, east, down
    v_ned_m_s: np.ndarray | None = None  # (M, 3)
    rpy_deg: np.ndarray | None = None  # (M, 3) attitude of the body (truth files only)

    def __len__(self):
        return self.t_s.size

    def select(self, keep):
        """The rows where `keep` (bool or index array) selects."""
        pick = {}
        for name in ("t_s", "lat_deg", "lon_deg", "h_m", "sigma_ned_m", "v_ned_m_s", "rpy_deg"):
            v = getattr(self, name)
            pick[name] = None if v is None else v[keep]
        return Positions(**pick)


@dataclass(eq=False)
class Dataset:
    """One drive: IMU, reference trajectory, optional GNSS input, and the installation."""

    name: str
    imu: Imu
    truth: Positions  # the reference trajectory
    truth_point: str  # "imu" (KF-GINS .nav) or "antenna" (an RTK solution of the antenna)
    gnss: Positions | None  # GNSS input as recorded; None: made from the truth (degraded)
    mount_rpy_deg: tuple  # sensor axes -> body FRD (module docstring)
    lever_frd_m: tuple  # IMU -> antenna
    gravity_m_s2: float | None = None  # local gravity if the source states it (information)
    description: str = ""
    # board configuration for this installation's sensor (noise, standstill thresholds:
    # names of firmware/lib/config.py), as a user would set it for their board
    board_config: dict = field(default_factory=dict)
    # where the parts came from, for messages: "imu", "truth", "gnss" -> a file name, and the
    # GPS week a KF-GINS dataset's sow columns count from (its dataset.yaml gpsweek)
    files: dict = field(default_factory=dict)
    gpsweek: int | None = None
    # surveyed points passed at known instants (t_s, lat, lon; no height): when given, the
    # reference is only true there (`truth` joins them for the replay's timing) and the
    # replay scores the output at these instants alone
    waypoints: Positions | None = None
