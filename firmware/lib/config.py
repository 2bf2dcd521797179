"""Board configuration persisted on the filesystem, CRC-32 protected, validated on load.

Binary, because a float written as text would be parsed differently on the board (MicroPython's
float32 parser is not correctly rounded) and on the desktop: the file holds float32 bit patterns,
so both see the same values. Layout, little-endian:
    b"INSC", version u8, record count u8, records, CRC-32 (u32) of everything before it
    record: id u8, kind u8 (0 int32, 1 float32), n u8, n values of 4 bytes
Unknown ids are skipped (a newer file on an older firmware), missing ids keep their defaults.

`load(path)` never raises: it returns (config, status) with status OK, MISSING, CORRUPT
(unreadable, bad magic or CRC) or INVALID (a value out of range); on anything but OK the config
is the defaults, and the caller reports it (console and health code). Runs at start-up only:
it allocates freely.
"""

import struct
from binascii import crc32

import f32
import mat
import navcfg
import rot

OK = 0
MISSING = 1
CORRUPT = 2
INVALID = 3
STATUS_TEXT = ("ok", "missing", "corrupt", "invalid")

_MAGIC = b"INSC"
_VERSION = 1
_INT = 0
_FLOAT = 1

# id, name, kind, count, default (floats as (num, den) integer ratios or raw values 0/1 only)
_SCHEMA = (
    (1, "profile", _INT, 1, 0),  # 0 car, 1 handheld
    (2, "gyro_range_dps", _INT, 1, 250),
    (3, "accel_range_g", _INT, 1, 2),
    (4, "output_every_ticks", _INT, 1, 1),  # 52-byte frame every n ticks (1: 200 Hz)
    (5, "output_baud", _INT, 1, 460800),
    (6, "ext_every_ticks", _INT, 1, 20),  # extended frame every n ticks, 0: off
    (7, "raw_record", _INT, 1, 0),  # 1: a raw-input record every tick (replay)
    (8, "gnss_baud", _INT, 1, 9600),
    # 2 (auto): the receiver's sentences decide what completes an epoch (drivers/gnss.py,
    # "Epochs"); overrides: 1 always a GGA and a speed sentence (RMC/VTG), 0 a GGA alone
    (9, "gnss_need_speed", _INT, 1, 2),
    (10, "coning", _INT, 1, 0),  # 1: two-sample coning and sculling corrections (navcfg)
    (11, "slices_per_tick", _INT, 1, 1),  # slices of filter work per tick (1..4, eskf.py)
    (12, "gnss_lag_learn", _INT, 1, 1),  # 1: search and apply the fixes' lag (nav_kern.lag_search)
    (20, "gyro_bias0", _FLOAT, 3, None),  # rad/s
    (21, "accel_bias0", _FLOAT, 3, None),  # m/s^2
    (22, "gyro_matrix", _FLOAT, 9, None),  # scale factor + misalignment (+ mounting)
    (23, "accel_matrix", _FLOAT, 9, None),
    (24, "lever_b_m", _FLOAT, 3, None),
    (25, "mount_ypr_deg", _FLOAT, 3, None),  # sensor axes vs body axes, rot.py's convention
    (30, "gyro_arw", _FLOAT, 1, None),
    (31, "accel_vrw", _FLOAT, 1, None),
    (32, "gyro_bias_sigma", _FLOAT, 1, None),
    (33, "accel_bias_sigma", _FLOAT, 1, None),
    (34, "gnss_latency_s", _FLOAT, 1, None),
    (35, "gnss_hdop_max", _FLOAT, 1, None),
    (36, "gate_sigma", _FLOAT, 1, None),
    (37, "gnss_uere_m", _FLOAT, 1, None),
    (38, "still_gyro", _FLOAT, 1, None),  # rad/s rms: standstill threshold (vibration)
    (39, "still_accel", _FLOAT, 1, None),  # m/s^2 rms of specific-force changes
    (40, "heading_speed_m_s", _FLOAT, 1, None),  # the course is the heading from this speed
    (41, "track_min_m", _FLOAT, 1, None),  # without a course: the chord that gives the heading
    (42, "track_max_s", _FLOAT, 1, None),  # ... within this long
    (43, "gnss_stamp_lag_s", _FLOAT, 1, None),  # the fixes' positions are older than their stamps
    # the UsartGPU screen (lib/status_page.py, docs/display.md): off by default, for on the
    # Black Pill its UART takes the USB pins
    (50, "display", _INT, 1, 0),  # 1: the status page on the screen's UART
    (51, "display_baud", _INT, 1, 115200),
    (52, "display_w", _INT, 1, 320),  # the screen's pixels
    (53, "display_h", _INT, 1, 240),
    (54, "display_fg", _INT, 1, 15),  # palette indices: text, background, warning, fault
    (55, "display_bg", _INT, 1, 0),
    (56, "display_warn", _INT, 1, 14),
    (57, "display_fault", _INT, 1, 12),
)
_GYRO_RANGES = (125, 250, 500, 1000, 2000)
_ACCEL_RANGES = (2, 4, 8, 16)
_BAUDS = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)
# Ranges of the float settings, every value (each element of a vector): name, low and high as
# integers over den (exact, no float literal), unit, and whether low itself is refused (a noise
# or threshold of 0). Each is what still navigates within the board spec with that setting alone
# changed, on the simulated car drive and walk: docs/benchmarks/settings.md (`make
# bench-settings`) has every value swept, its figures and the one past each end (below: what
# fails there). A value outside is a mistake (a unit mix-up, a typo, a wrong calibration) that
# the filter would pay for in metres or never navigate with.
_RANGES = (
    # the BMI055's offset (~1 deg/s) plus half the run of calibration errors that pass (-0.001
    # ..0.005 on every axis); -0.002: drive 3.4 m, 0.007: drive velocity 1 m/s
    ("gyro_bias0", -205, 205, 10000, "rad/s", False),
    # the BMI055's offset (~70 mg) plus half the passing run (-0.24..0.2); 0.24: walk yaw 3.3 deg
    ("accel_bias0", -92, 92, 100, "m/s^2", False),
    # a rotation's elements (a mounting) times the scales that pass (0.99..1.01) and the
    # BMI055's scale error (1 %); 1.02 on the diagonal: drive velocity 0.11 m/s
    ("gyro_matrix", -102, 102, 100, "", False),
    ("accel_matrix", -102, 102, 100, "", False),  # the same: 1.02: 0.09 m/s
    # an antenna there navigates the car; 4 m on every axis: drive velocity 0.11 m/s (in
    # hand the walk fails from 3 cm: the sweep's union, docs/benchmarks/settings.md)
    ("lever_b_m", -3, 3, 1, "m", False),
    ("mount_ypr_deg", -180, 180, 1, "deg", False),  # any mounting navigates, told right
    # 4e-3: walk 3.4 m, yaw 3.4 deg; below 1e-5 not swept (BMI055: 5e-4 with margin)
    ("gyro_arw", 1, 300, 100000, "rad/s/sqrt(Hz)", False),
    ("accel_vrw", 1, 700, 10000, "m/s^2/sqrt(Hz)", False),  # 0.1: walk yaw 3.5 deg
    ("gyro_bias_sigma", 1, 5000, 1000000, "rad/s", False),  # 0.007: walk yaw 4.3 deg
    ("accel_bias_sigma", 1, 2400, 10000, "m/s^2", False),  # 0.3: walk 3.6 m
    # 1: navigating 68 s late (the fixes' HDOP is ~1); 3: drive frames 10 m off, not health 2
    ("gnss_hdop_max", 12, 27, 10, "", False),
    ("gate_sigma", 35, 1000, 10, "sigmas", False),  # 3: walk 18 m (user: 1 gave 28 m)
    # 0.7: drive velocity 0.11 m/s (user: 0.001 gave 98 m); 10: walk velocity 0.93 m/s
    ("gnss_uere_m", 1, 7, 1, "m", False),
    # from the car's default (0.007: 0.64 m/s) to the hand's and beyond (0.2: the end)
    ("still_gyro", 87, 2000, 10000, "rad/s", False),
    ("still_accel", 4, 500, 100, "m/s^2", False),  # 0.035: drive 0.65 m/s
    ("heading_speed_m_s", 1, 10, 10, "m/s", False),  # 2: the walk never navigates
    # GGA-only receivers: 8 m: walk frames 10 m off without health 2; 20 m: walk 6.1 m
    ("track_min_m", 12, 15, 1, "m", False),
    ("track_max_s", 10, 120, 1, "s", False),  # 7: walk 12 m
    ("gnss_stamp_lag_s", 0, 3, 10, "s", False),  # fixes that late, told so: the car navigates
)


def _nav_defaults(profile):
    """{name: default} of the float settings the navigator's profile sets (navcfg)."""
    nav = navcfg.NavConfig("handheld" if profile == 1 else "car")
    out = {}
    for _id, name, kind, n, _default in _SCHEMA:
        if kind != _FLOAT or name in ("gyro_matrix", "accel_matrix", "mount_ypr_deg"):
            continue
        v = getattr(nav, name)
        out[name] = v if n == 1 else [v[i] for i in range(n)]
    return out


class BoardConfig:
    """Every persisted setting; floats default to the navigator's defaults (navcfg) of the
    profile (the standstill thresholds differ: a hand is never still like a parked car)."""

    def __init__(self, profile=0):
        nav = _nav_defaults(profile)
        for _id, name, kind, _n, default in _SCHEMA:
            if kind == _INT:
                setattr(self, name, default)
            elif name in ("gyro_matrix", "accel_matrix"):
                setattr(self, name, None)  # identity
            elif name == "mount_ypr_deg":
                setattr(self, name, [0.0, 0.0, 0.0])  # sensor axes = body axes
            else:
                setattr(self, name, nav[name])
        self.profile = profile

    def set(self, name, value):
        """Set one setting. A change of profile also moves every float setting still at the
        old profile's default to the new one's: a car's standstill thresholds left in a file
        would stop a hand's zero-velocity updates; values the user chose stay."""
        if name == "profile" and value != self.profile and value in (0, 1):
            old = _nav_defaults(self.profile)
            for key, default in _nav_defaults(value).items():
                if getattr(self, key) == old[key]:
                    setattr(self, key, default)
        setattr(self, name, value)

    def apply(self, changes):
        """set() each (name, value), the profile first, so that a value given with it stays."""
        for name, value in changes:
            if name == "profile":
                self.set(name, value)
        for name, value in changes:
            if name != "profile":
                self.set(name, value)

    def nav_config(self):
        """The navigator's configuration with these settings applied."""
        nav = navcfg.NavConfig("handheld" if self.profile == 1 else "car")
        for _id, name, kind, n, _default in _SCHEMA:
            if kind != _FLOAT or not hasattr(nav, name):
                continue
            value = getattr(self, name)
            if value is None:
                setattr(nav, name, None)
            elif n == 1:
                setattr(nav, name, f32.f32(value))
            else:
                b = f32.zeros(n)
                for i in range(n):
                    b[i] = value[i]
                setattr(nav, name, b)
        nav.coning = self.coning == 1
        nav.slices_per_tick = self.slices_per_tick
        nav.gnss_lag_learn = self.gnss_lag_learn == 1
        _apply_mounting(nav, self.mount_ypr_deg)
        # the sensor ranges set the raw-count scale (BMI055 datasheet sensitivities)
        nav.gyro_counts_per_rad_s = f32.ratio(GYRO_LSB_X10[self.gyro_range_dps], 10) / _DEG
        nav.accel_counts_per_m_s2 = f32.f32(ACCEL_LSB[self.accel_range_g]) / navcfg.G0_M_S2
        return nav

    def validate(self):
        """None if every value is in range, else a message naming the first bad one."""
        if self.profile not in (0, 1):
            return "profile must be 0 (car) or 1 (handheld)"
        if self.gyro_range_dps not in _GYRO_RANGES:
            return f"gyro_range_dps must be one of {_GYRO_RANGES}"
        if self.accel_range_g not in _ACCEL_RANGES:
            return f"accel_range_g must be one of {_ACCEL_RANGES}"
        for name in ("output_baud", "gnss_baud"):
            if getattr(self, name) not in _BAUDS:
                return f"{name} must be one of {_BAUDS}"
        if not 1 <= self.output_every_ticks <= 200:
            return "output_every_ticks must be 1..200"
        if not 0 <= self.ext_every_ticks <= 2000:
            return "ext_every_ticks must be 0..2000"
        if self.raw_record not in (0, 1):
            return "raw_record must be 0 or 1"
        if self.gnss_need_speed not in (0, 1, 2):
            return "gnss_need_speed must be 2 (auto), 1 (GGA and RMC/VTG) or 0 (GGA alone)"
        if self.coning not in (0, 1):
            return "coning must be 0 or 1"
        if not 1 <= self.slices_per_tick <= 4:
            return "slices_per_tick must be 1..4"
        if self.gnss_lag_learn not in (0, 1):
            return "gnss_lag_learn must be 0 or 1"
        problem = self._display_problem()
        if problem:
            return problem
        for _id, name, kind, _n, _default in _SCHEMA:
            value = getattr(self, name)
            if kind != _FLOAT or value is None:
                continue
            for x in value if isinstance(value, list) else (value,):
                if not x - x == 0.0:
                    return f"{name} is not finite"
        # The ranges are checked on float32s alone: the value as the file holds it and the
        # range's ends as float32 (x, lo, hi: elements of a float32 buffer), compared with each
        # other and no arithmetic on the value. A comparison of two float32s is exact in any
        # precision, so the verdict is the same on the board (float32 floats), on the desktop
        # (the tool's Python doubles, rounded to float32 by the store as config.encode rounds
        # them; the NumPy model) and in the double-precision MicroPython VM. The ends are
        # f32.ratio(lo, den), the float32 nearest lo / den: a double quotient rounded to
        # float32 (the VM) is that same float32. Not `x * den` against integers: that product
        # rounds differently in float32 and in double (0.1 as a float32 times 10 is 1 on the
        # board, 1.0000000149 on the desktop).
        r = f32.zeros(3)
        for name, lo, hi, den, unit, open_low in _RANGES:
            value = getattr(self, name)
            if value is None:
                continue
            r[1] = f32.ratio(lo, den)
            r[2] = f32.ratio(hi, den)
            for x in value if isinstance(value, list) else (value,):
                r[0] = x
                if r[0] < r[1] or r[0] > r[2] or (open_low and r[0] <= r[1]):
                    text = f"{name} must be within {_dec(lo, den)}..{_dec(hi, den)}"
                    return text + (" " + unit if unit else "") + (", above 0" if open_low else "")
        r[0] = self.gnss_latency_s  # the same rule: the float32 against 0 and 1
        if not 0.0 <= r[0] < 1.0:
            return "gnss_latency_s must be in [0, 1) s"
        return None

    def _display_problem(self):
        if self.display not in (0, 1):
            return "display must be 0 (off) or 1 (on)"
        if self.display_baud not in _BAUDS or self.display_baud < 38400:
            return f"display_baud must be one of {_BAUDS[2:]}"
        if not (220 <= self.display_w <= 480 and 176 <= self.display_h <= 320):
            return "display_w x display_h must be within 220..480 x 176..320 pixels"
        for name in ("display_fg", "display_bg", "display_warn", "display_fault"):
            if not 0 <= getattr(self, name) <= 255:
                return f"{name} must be a palette index, 0..255"
        return None


def _dec(num, den):
    """num / den (den a power of ten) as a decimal, without a float: -35, 100 -> "-0.35"."""
    q, r = divmod(abs(num), den)
    s = str(q)
    if r:
        s += "." + ("0" * len(str(den)) + str(r))[-(len(str(den)) - 1) :].rstrip("0")
    return ("-" if num < 0 else "") + s


def _apply_mounting(nav, ypr_deg):
    """x_b = C_mount M (x_raw - b0): C_mount = rot.euler_to_dcm of the sensor axes' yaw,
    pitch, roll relative to the body, composed into both calibration matrices."""
    if ypr_deg[0] == 0.0 and ypr_deg[1] == 0.0 and ypr_deg[2] == 0.0:
        return
    ypr = f32.zeros(3)
    for i in range(3):
        ypr[i] = f32.f32(ypr_deg[i]) * _DEG
    c = f32.zeros(9)
    rot.euler_to_dcm(c, ypr)
    for name in ("gyro_matrix", "accel_matrix"):
        m = getattr(nav, name)
        out = f32.zeros(9)
        if m is None:
            mat.copy(out, c, 9)
        else:
            mat.mul(out, c, m, 3, 3, 3)
        setattr(nav, name, out)


GYRO_LSB_X10 = {125: 2624, 250: 1312, 500: 656, 1000: 328, 2000: 164}  # LSB per deg/s x10
ACCEL_LSB = {2: 1024, 4: 512, 8: 256, 16: 128}  # LSB per g (12-bit)
_DEG = f32.from_bits(0x3C8EFA35)  # pi / 180


def _fmt(kind, n):
    return "<{}{}".format(n, "i" if kind == _INT else "f")


def encode(cfg):
    """The file's bytes for a BoardConfig."""
    parts = [_MAGIC, bytes((_VERSION, len(_SCHEMA)))]
    for rid, name, kind, n, _default in _SCHEMA:
        value = getattr(cfg, name)
        if value is None:  # identity matrix
            value = [1.0 if i % 4 == 0 else 0.0 for i in range(9)]
        values = value if isinstance(value, list) else [value]
        parts.append(bytes((rid, kind, n)) + struct.pack(_fmt(kind, n), *values))
    body = b"".join(parts)
    return body + struct.pack("<I", crc32(body) & 0xFFFFFFFF)


def decode(data):
    """A BoardConfig from the file's bytes; ValueError if they are not a valid file."""
    if len(data) < 10 or data[:4] != _MAGIC:
        raise ValueError("not a configuration file (bad magic)")
    body = data[:-4]
    (want,) = struct.unpack("<I", data[-4:])
    if crc32(body) & 0xFFFFFFFF != want:
        raise ValueError("CRC-32 mismatch")
    if data[4] != _VERSION:
        raise ValueError(f"unsupported version {data[4]}")
    cfg = BoardConfig()
    by_id = {}
    for rid, name, kind, n, _default in _SCHEMA:
        by_id[rid] = (name, kind, n)
    pos = 6
    changes = []
    for _ in range(data[5]):
        if pos + 3 > len(body):
            raise ValueError("truncated record")
        rid, kind, n = body[pos], body[pos + 1], body[pos + 2]
        end = pos + 3 + 4 * n
        if end > len(body) or kind not in (_INT, _FLOAT):
            raise ValueError("truncated or malformed record")
        values = list(struct.unpack(_fmt(kind, n), body[pos + 3 : end]))
        pos = end
        if rid not in by_id:
            continue  # written by a newer firmware
        name, want_kind, want_n = by_id[rid]
        if kind != want_kind or n != want_n:
            raise ValueError(f"record {name} has the wrong shape")
        value = values[0] if n == 1 else values
        if name.endswith("_matrix") and value == [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]:
            value = None
        changes.append((name, value))
    cfg.apply(changes)  # a record the file lacks: the default of its profile
    return cfg


def load(path):
    """(config, status): the file's configuration if it is present, intact and valid, else
    the defaults with the reason (MISSING, CORRUPT or INVALID) and a message."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError:
        return BoardConfig(), MISSING, f"no configuration file {path}: using defaults"
    try:
        cfg = decode(data)
    except (ValueError, IndexError) as e:
        return BoardConfig(), CORRUPT, f"configuration {path} is corrupt ({e}): using defaults"
    problem = cfg.validate()
    if problem:
        return (
            BoardConfig(),
            INVALID,
            f"configuration {path} is invalid ({problem}): using defaults",
        )
    return cfg, OK, f"configuration {path} loaded"


def save(path, cfg):
    """Write cfg (validated first: ValueError names the bad value)."""
    problem = cfg.validate()
    if problem:
        raise ValueError(problem)
    data = encode(cfg)
    with open(path, "wb") as f:
        f.write(data)
