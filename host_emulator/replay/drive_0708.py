"""The drive_0708 recording (docs/requirements.md, real drive drive_0708): a 549 s car drive with a
low-cost 100 Hz IMU and an RTK solution of the antenna (rtklibexplorer, BSD-3; read from
../shared/data/drive_0708).

Files and how they are read:
- `imu_1934.csv`: ax, ay, az [g], gx, gy, gz [deg/s], t [ms of the IMU's own clock], 100 Hz.
- `imu_1934.csv.tag`: RTKLIB time tag: a 60-byte header, uint32 tick_f, uint32 time_t (whole
  GPST seconds as a Unix time), float64 fraction -> the start time (GPST 2025-07-08
  19:34:21.854), then (uint32 tick ms, uint32 file position) pairs; the last tick is how long
  the logger ran.
- `gnss_1934_sf.pos`: the RTK solution (host_emulator.replay.rtklib_pos reads it).

Time alignment, as the publisher's own conversion does it: the IMU clock is mapped linearly
onto GPST from the tag's start to the tag's end (first row -> start, last row -> start + last
tick; the IMU clock runs 257 ppm slow against GPST over the drive), the first and last rows
are dropped (they may be partial) and every time is shifted by -0.125 s (the logger's delay).
Each row is taken as the mean over the 10 ms before its time. On top of that this loader moves
the IMU 0.04 s earlier: its yaw rate then fits the rate of the RTK course best, whether the
course is taken from the RTK velocities (aligned as below) or from the RTK positions
(tests/replay/test_drive_0708.py measures -0.035 and -0.045 s on a 5 ms grid before the shift).
The replay's horizontal RMS goes from 1.24 to 1.20 m with it.

The .pos velocities (vn, ve, vu) lag its positions by half an epoch: they match the
derivative of the positions 0.125 s earlier (tests/replay/test_drive_0708.py), as a
difference over the preceding 0.25 s would. The loader moves them 0.125 s earlier, so that
velocity errors are not scored against a reference that is late by 0.125 s (at 1 m/s^2 that
alone is 0.125 m/s).

Units: g is multiplied by the local gravity the publisher uses (9.7969 m/s^2), so the
accelerometer's ~1.3 % scale excess at rest stays a bias for the filter, as it would be on a
board. Mounting [180, -6.79, 185.35] deg and lever arm [0, 0.05, 0] m FRD (the publisher's).
"""

import pathlib
import struct

import numpy as np

from common.errors import EmulatorError
from host_emulator.replay import dataset as ds
from host_emulator.replay import rtklib_pos

NAME = "drive_0708"
REPO_DIR = pathlib.Path(__file__).resolve().parents[2]
DEFAULT_DIR = REPO_DIR.parent / "shared" / "data" / "drive_0708"
IMU_FILE = "imu_1934.csv"
TAG_FILE = "imu_1934.csv.tag"
POS_FILE = "gnss_1934_sf.pos"

GRAVITY_M_S2 = 9.7969
MOUNT_RPY_DEG = (180.0, -6.79, 185.35)
LEVER_FRD_M = (0.0, 0.05, 0.0)
LOGGER_DELAY_S = 0.125
IMU_EXTRA_DELAY_S = 0.04  # measured against the RTK course (module docstring)
POS_VELOCITY_LAG_S = 0.125
# This IMU is not a BMI055: parked with the engine running it shows 0.07-0.14 m/s^2 and up to
# 2.4 deg/s (pitch axis) of vibration at 100 Hz (tests/replay/test_drive_0708.py), far above
# the BMI055 datasheet noise the firmware defaults to. Its board settings, chosen from that
# vibration and a sweep of the replay on this drive (docs/accuracy.md compares them with the
# defaults): gyro ARW 0.1 deg/s/sqrt(Hz) (default 0.028), accel VRW 1 mg/sqrt(Hz) (default
# 0.3), standstill when the rms of rotation stays under 3 deg/s and of specific-force changes
# under 0.3 m/s^2 (above the parked vibration, below normal driving).
BOARD_CONFIG = {
    "gyro_arw": 0.0017,  # rad/s/sqrt(Hz)
    "accel_vrw": 0.01,  # m/s^2/sqrt(Hz)
    "still_gyro": 0.0524,  # rad/s (3 deg/s)
    "still_accel": 0.3,  # m/s^2
}
_TAG_HEADER = 60
_UNIX_TO_GPS_S = 315964800  # 1980-01-06 as a Unix time (the tag's time_t counts GPST)


def read_tag(path):
    """(start GPST s, last tick s) of an RTKLIB time-tag file."""
    raw = pathlib.Path(path).read_bytes()
    if len(raw) < _TAG_HEADER + 24 or not raw.startswith(b"TIMETAG"):
        raise EmulatorError(f"{path}: not an RTKLIB time-tag file")
    _tick_f, time_t, frac = struct.unpack_from("<IId", raw, _TAG_HEADER)
    pairs = np.frombuffer(raw, "<u4", offset=_TAG_HEADER + 16)
    if pairs.size < 2 or pairs.size % 2:
        raise EmulatorError(f"{path}: truncated time-tag pairs")
    return time_t - _UNIX_TO_GPS_S + frac, float(pairs[-2]) * 1e-3


def read_imu(csv_path, tag_path):
    """Imu in the sensor's axes on GPST (module docstring)."""
    try:
        a = np.loadtxt(csv_path, delimiter=",", ndmin=2)
    except (OSError, ValueError) as e:
        raise EmulatorError(f"{csv_path}: cannot read the IMU file ({e})") from None
    if a.shape[1] != 7 or a.shape[0] < 100:
        raise EmulatorError(f"{csv_path}: expected rows of 7 columns (ax..gz, t)")
    t_ms = a[:, 6]
    if np.any(np.diff(t_ms) <= 0):
        raise EmulatorError(f"{csv_path}: the IMU clock does not increase")
    start, span = read_tag(tag_path)
    t = start + (t_ms - t_ms[0]) * (span / (t_ms[-1] - t_ms[0]))
    keep = slice(1, -1)
    return ds.Imu(
        t_s=t[keep] - (LOGGER_DELAY_S + IMU_EXTRA_DELAY_S),
        gyro_rad_s=np.radians(a[keep, 3:6]),
        accel_m_s2=a[keep, 0:3] * GRAVITY_M_S2,
    )


def align_velocity(t_s, v, lag_s):
    """Velocities v (M, 3) at t_s that are lag_s late, moved onto t_s (ends held)."""
    return np.stack([np.interp(t_s + lag_s, t_s, v[:, j]) for j in range(3)], axis=-1)


def load(data_dir=None):
    """The drive as a Dataset (truth = the RTK solution of the antenna, no GNSS input: the
    replay degrades the truth into it)."""
    d = pathlib.Path(data_dir) if data_dir else DEFAULT_DIR
    for name in (IMU_FILE, TAG_FILE, POS_FILE):
        if not (d / name).is_file():
            raise EmulatorError(
                f"{d / name} not found: drive_0708 is read from ../shared/data/drive_0708 "
                "beside the repository (or give --data DIR)"
            )
    imu = read_imu(d / IMU_FILE, d / TAG_FILE)
    truth = rtklib_pos.read(d / POS_FILE).positions
    truth.v_ned_m_s = align_velocity(truth.t_s, truth.v_ned_m_s, POS_VELOCITY_LAG_S)
    return ds.Dataset(
        name=NAME,
        imu=imu,
        truth=truth,
        truth_point="antenna",
        gnss=None,
        mount_rpy_deg=MOUNT_RPY_DEG,
        lever_frd_m=LEVER_FRD_M,
        gravity_m_s2=GRAVITY_M_S2,
        description="real car drive, 100 Hz low-cost IMU, RTK truth (rtklibexplorer, BSD-3)",
        board_config=dict(BOARD_CONFIG),
    )
