"""The board's output stream computed by the NumPy float32 model, mirroring firmware/app.py:
the parity oracle of the cpython runtime (eval/parity.py).

    out = run(stim)        # bytes: what firmware/app.py would send for this stimulus

Modelled independently here (NumPy float32, or plain integers):
- the navigator: model/nav.py's NavModel (bit-exact with firmware/lib/nav.py, proven by
  tests/model/test_nav_model.py), fed every tick as app.py feeds the Navigator;
- BMI055 decoding and the over-range flag, vectorised from the stimulus registers;
- the GNSS UART: the receive ring (board.py's rxbuf, bytes beyond it lost) and the loop's
  reads of at most app._RX_LEN bytes per tick;
- the virtual clock: tick k at t_k = t0 + k tick_us, PPS edges at t_k - pps_before_us,
  MicroPython's 30-bit ticks_us/ticks_diff; t0 is derived from the BMI055 driver's start-up
  waits (GYRO_RESET_MS + ACCEL_RESET_MS, rounded up to the next tick moment; checked in
  tests/eval/test_parity.py against the tick start times the firmware's raw records carry);
- app._deliver_fix: lat/lon split, height in dm (an epoch without one: the last one the
  receiver gave; before any, 0 in the frame and no fix for the navigator), f32 ratios for
  height, HDOP and speed, course x pi/18000 (rebuilt from its float32 bits), speed and
  course -1 when unknown, the fallback HDOP, the no-fix epoch and the measurement tick from
  the PPS edge (or -1: the configured latency);
- the 52-byte frame, vectorised over all ticks (proto/frame.py's table as a NumPy record
  type): euler angles through model/rot.py,
  x * scale in float32 rounded half away from zero, clamped, NaN -> 0; the sensor fields'
  integer conversions; the checksum;
- the extended frame 0x91 (P diagonal, biases, position and the origin's height as the
  model's float32 bits; the tick timing, overrun and GC fields are 0 as on the emulator,
  whose loop takes no virtual time and whose heap never runs low) and the raw-input record
  0x92, encoded by proto/records.py.
Shared with the firmware (integer or bit-level code, validated on its own):
- the NMEA parser `drivers/gnss.py` Nmea (checked against gpsd on real logs), including its
  `pps_isr`, which stamps the edge from the emulated board's virtual clock
  (emulated_board/mpy/time.py), and its flag/epoch "take" methods;
- the configuration: the file the runtimes write (proto/config.py) is decoded by
  firmware/lib/config.py and `BoardConfig.nav_config()` builds the navigator's configuration,
  as on the board (an explicit identity matrix becomes None there, for instance);
- constants of firmware modules: the BMI055 driver's sensitivities, over-range thresholds
  and reset waits; NavModel and the reference rot/fmath models use the firmware's constants.
Not modelled: a missing IMU (the emulated BMI055 always answers), overruns, garbage
collection, tick timing (none of them happen on the emulator).
"""

import functools
import time  # CPython's, with the board's ticks_us and set_us once install_machine() ran

import numpy as np

from common import firmware_env
from common.proto import config as board_config
from common.proto import frame as frame_schema
from common.proto import records
from common.proto import stimulus as stim_mod
from common.proto.ticks import TICKS_PERIOD, ticks_diff
from host_emulator.emulated_board import install_machine
from host_emulator.model import display
from host_emulator.model import rot as ref_rot
from host_emulator.model.nav import NavModel

firmware_env.install()
import config  # noqa: E402  (firmware/lib/config.py: the board's configuration file)
import geo as fw_geo  # noqa: E402  (the origin height's index; the longitude's e7 join)
import nav_kern  # noqa: E402  (radians per centidegree of course)
from drivers.gnss import Nmea  # noqa: E402  (the shared NMEA parser)

F32 = np.float32
_FRAME = frame_schema.numpy_dtype()
_PPS_MAX_AGE_US = 1_000_000  # an older PPS edge is not the fix's (app._deliver_fix)
_I32_LIM = 1073741823  # frame.put_scaled32's clamp (small ints on the board)


@functools.cache
def _firmware():
    """The firmware's modules whose constants the model uses: app, board, frame and the BMI055
    driver (sensitivities, over-range thresholds, reset waits); imported once."""
    return tuple(map(firmware_env.import_module, ("app", "board", "frame", "drivers.bmi055")))


def first_tick_us(tick_us):
    """t0: the first timer moment after the firmware's start-up, whose only virtual time is
    the BMI055 driver's waits after the two soft resets (us since power-on)."""
    bmi055 = _firmware()[3]
    startup_us = 1000 * (bmi055.GYRO_RESET_MS + bmi055.ACCEL_RESET_MS)
    return -(-startup_us // tick_us) * tick_us


def _round_div(num, den):
    """num / den rounded half away from zero, elementwise in int64 (den > 0)."""
    num = np.asarray(num, np.int64)
    pos = (2 * num + den) // (2 * den)
    neg = -((-2 * num + den) // (2 * den))
    return np.where(num >= 0, pos, neg)


def _round_clamp(y, lo, hi):
    """Float32 y rounded half away from zero in float32 (int(y + 0.5), -int(0.5 - y)),
    clamped to [lo, hi]; NaN -> 0 (frame._round_clamp, elementwise)."""
    y = np.asarray(y, F32)
    half = F32(0.5)
    with np.errstate(invalid="ignore", over="ignore"):
        up = np.trunc(np.where(y >= 0, y + half, half - y))
        r = np.where(np.isfinite(up), up, 0).astype(np.int64)
        r = np.where(y >= 0, r, -r)
        r = np.where(y != y, 0, r)
        r = np.where(y <= F32(lo), lo, r)
        return np.where(y >= F32(hi), hi, r)


def frame_bytes(t, cfg):
    """(F, 52) uint8: the frames of the ticks in t (dict of per-frame arrays, see `run`)."""
    fw_app, _, fw_frame, bmi055 = _firmware()
    f = len(t["counter"])
    fr = np.zeros(f, _FRAME)
    fr["header0"] = frame_schema.HEADER
    fr["header1"] = frame_schema.FRAME_TYPE
    fr["counter"] = t["counter"]
    lsb_x10 = bmi055.GYRO_LSB_PER_DPS_X10[cfg.gyro_range_dps]
    lsb_g = bmi055.ACCEL_LSB_PER_G[cfg.accel_range_g]
    gyro = np.clip(_round_div(t["gyro"] * fw_frame._GYRO_FRAME_X100, 10 * lsb_x10), -32768, 32767)
    accel = np.clip(_round_div(t["accel"] * fw_frame._ACCEL_FRAME, lsb_g), -32768, 32767)
    ypr = ref_rot.dcm_to_euler(t["c_bn"])  # (F, 3) yaw, pitch, roll, rad
    ypr = _round_clamp(ypr * nav_kern.CDEG_PER_RAD, -32768, 32767)
    vel = _round_clamp(t["v_n"] * F32(100), -32768, 32767)
    for i, (xyz, enu) in enumerate(zip("xyz", "enu", strict=True)):
        fr[f"gyro_{xyz}"] = gyro[:, i]
        fr[f"accel_{xyz}"] = accel[:, i]
        fr[f"vel_{enu}_cm_s"] = vel[:, i]
    for i, name in enumerate(("yaw_cdeg", "pitch_cdeg", "roll_cdeg")):
        fr[name] = ypr[:, i]
    fr["pps"] = t["pps"]
    fr["gga"] = t["gga"]
    fr["gnss_valid"] = t["valid"]
    fr["lat_e7"] = t["lat_e7"]
    fr["lon_e7"] = t["lon_e7"]
    fr["height_dm"] = np.clip(t["height_dm"], -32768, 32767)
    fr["nav_state"] = t["state"] & 0xFF
    fr["pos_e_cm"] = _round_clamp(t["p_n"][:, 0] * F32(100), -_I32_LIM, _I32_LIM)
    fr["pos_n_cm"] = _round_clamp(t["p_n"][:, 1] * F32(100), -_I32_LIM, _I32_LIM)
    fr["pos_u_dm"] = _round_clamp(t["p_n"][:, 2] * F32(10), -32768, 32767)
    b = fr.view(np.uint8).reshape(f, frame_schema.FRAME_LEN)
    b[:, -1] = b[:, 2:-1].sum(axis=1, dtype=np.int64) & 0xFF
    return b


def ext_frame(counter, health, state, cfg_status, flags, model, causes, overruns=0):
    """The extended frame (proto/records.py) of the model's state after this tick; overruns:
    the ticks the loop missed so far (on the emulator, whose loop takes no virtual time, only
    injected stalls)."""
    ins = model.ins
    return records.encode_ext(
        counter,
        {
            "health": health,
            "nav_state": state,
            "config_status": cfg_status,
            "flags": flags,
            # the board's run time: 0 on the emulator, whose loop takes no virtual time
            "worst_tick_us": 0,
            "mean_tick_us": 0,
            "overruns": overruns & 0xFFFF,
            "gc_runs": 0,
            "p_diag": model.p_diag(),
            "gyro_bias_rad_s": ins.bg,
            "accel_bias_m_s2": ins.ba,
            "pos_enu_m": ins.p_n,
            "origin_lat_e7": model.origin_lat_e7,
            "origin_lon_e7": model.origin_lon_e7,
            "tick": model.tick & 0x3FFFFFFF,
            "origin_h_m": model.coef[fw_geo.H0],
            "causes": causes,
        },
    )


class _Fix:
    """The app's fix fields for the frame (lat/lon in 1e-7 deg, height in dm, valid)."""

    def __init__(self):
        self.valid = 0
        self.lat_e7 = 0
        self.lon_e7 = 0
        self.height_dm = 0
        self.msl_mm = 0  # the last height the receiver gave (app._K_MSL_MM, _K_H_MM)
        self.h_mm = None  # None: none yet (the navigator gets no fix)


def deliver_fix(g, model, fix, hdop_max, now_us, pps, ticks):
    """app._deliver_fix on the model: g is the parser with a completed epoch; now_us the
    tick's ticks_us value; pps the app's PPS check state ("last" edge, "bad" until), ticks
    the app's tick count."""
    fw_app = _firmware()[0]
    _nmea_seen(g, pps, ticks)
    ok = bool(g.epoch_pos_ok) and g.epoch_quality > 0
    fix.valid = 1 if ok and not g.epoch_bad else 0
    if not fix.valid:  # a no-fix epoch (quality 0), or a fix with an impossible field (-1)
        model.gnss(0, 0, 0.0, -1 if ok else 0, F32(99), -1.0, -1.0)
        return
    lat = g.epoch_lat_e7
    lon = fw_geo.join_e7(g.epoch_lon_deg, g.epoch_lon_frac_e7)
    fix.lat_e7 = lat
    fix.lon_e7 = lon
    if g.epoch_alt_ok:  # else the last height the receiver gave (app._fix_fields)
        fix.msl_mm = g.epoch_alt_mm
        fix.h_mm = g.epoch_alt_mm + (g.epoch_sep_mm if g.epoch_sep_ok else 0)
    alt_mm = fix.h_mm
    fix.height_dm = int(_round_div(fix.msl_mm, 100))
    hdop = F32(hdop_max)
    if g.epoch_hdop_x100 >= 0:
        hdop = F32(g.epoch_hdop_x100) / F32(100)
    speed = -1.0  # no speed in the epoch: unknown
    course = -1.0
    if g.epoch_speed_mm_s >= 0:
        speed = F32(g.epoch_speed_mm_s) / F32(1000)
        if g.epoch_course_cdeg >= 0:
            course = F32(g.epoch_course_cdeg) * nav_kern.RAD_PER_CDEG
    fix_tick = -1
    age_us = ticks_diff(now_us, g.epoch_pps_us)
    if g.epoch_utc_ms > 0:  # app._fix_tick: from the fix's own moment in its second
        age_us -= g.epoch_utc_ms % 1000 * 1000
    if g.epoch_pps_us and 0 <= age_us < _PPS_MAX_AGE_US:
        if _late_s(pps, g.epoch_pps_us, g.epoch_utc_ms, ticks) > 0:  # app._fix_tick: too old
            model.gnss(0, 0, 0.0, 0, F32(99), -1.0, -1.0)
            return
        fix_tick = model.tick - age_us // fw_app._US_PER_TICK
    elif pps["last"]:  # app._fix_tick: no edge for this fix though edges came before
        pps["bad"] = ticks + fw_app._SECOND_TICKS
    if alt_mm is None:  # no height yet (an RMC-only receiver): nav_kern.fix_in
        model.gnss(lat, lon, 0.0, g.epoch_quality, hdop, speed, course, fix_tick, sigma_v_m=-1.0)
        return
    h = F32(alt_mm) / F32(1000)
    model.gnss(lat, lon, h, g.epoch_quality, hdop, speed, course, fix_tick)


def _late_s(pps, p_us, utc_ms, ticks):
    """app._late_s: whole seconds by which edge p_us is later than the epoch's UTC second,
    counted from the edge of the last on-time epoch (pps "edge_us", "edge_s"), which a 0
    count, a first epoch or an old reference replace; an edge off the seconds is not counted.
    A lateness that begins while the edges were regular ("edges_ok"), or of 2 s or more, is
    a clock step:
    re-referenced after _STEP_EPOCHS epochs with it ("step_s", "step_n"); one that began at a
    missed edge stays late; a negative count re-references at once; the causes' deadlines
    ("late_bad", "step_bad") at `ticks`."""
    fw_app = _firmware()[0]
    if utc_ms < 0:
        return 0
    s = utc_ms // 1000
    if pps["edge_s"] >= 0:
        d = ticks_diff(p_us, pps["edge_us"])
        if abs(d) < fw_app._EDGE_REF_MAX_US:
            r = (d + 500_000) % 1_000_000 - 500_000
            if abs(r) > fw_app._PPS_TOL_US:
                return 0
            late = (pps["edge_s"] + (d + 500_000) // 1_000_000 - s) % fw_app._DAY_S
            if 0 < late < fw_app._DAY_S // 2:
                if late != pps["step_s"]:
                    pps["step_s"] = late
                    regular = pps["edges_ok"] >= fw_app._OVERDUE_EDGES
                    pps["step_n"] = 0 if regular or late > 1 else -1
                if pps["step_n"] < 0:
                    pps["late_bad"] = ticks + fw_app._SECOND_TICKS
                    return late
                pps["step_bad"] = ticks + fw_app._SECOND_TICKS
                pps["step_n"] += 1
                if pps["step_n"] < fw_app._STEP_EPOCHS:
                    return late
            elif late:
                pps["step_bad"] = ticks + fw_app._SECOND_TICKS
    pps["edge_us"] = p_us
    pps["edge_s"] = s
    pps["step_s"] = 0
    return 0


def _pps_seen(g, pps, ticks):
    """app._pps_seen, at the frame tick that takes an edge's flag: a spurious edge, the run of
    edges that each had an epoch and the tick the next epoch is overdue from, the rejected
    sentences."""
    fw_app = _firmware()[0]
    pps["edges_ok"] = pps["edges_ok"] + 1 if g.epoch_pps_us == pps["last"] else 0
    if pps["last"]:
        d = (ticks_diff(g.pps_us, pps["last"]) + 500_000) % 1_000_000 - 500_000
        if abs(d) > fw_app._PPS_TOL_US:
            pps["bad"] = ticks + fw_app._SECOND_TICKS
            pps["edges_ok"] = 0
    pps["last"] = g.pps_us
    pps["overdue"] = fw_app._NEVER
    if pps["edges_ok"] >= fw_app._OVERDUE_EDGES:
        pps["overdue"] = ticks + fw_app._OVERDUE_TICKS
    _nmea_seen(g, pps, ticks)


def _nmea_seen(g, pps, ticks):
    """app._pps_seen and _deliver_fix: sentences rejected since the last look."""
    if g.rejected() != pps["nmea"]:
        pps["nmea"] = g.rejected()
        pps["nmea_bad"] = ticks + _firmware()[0]._SECOND_TICKS


def run(stim, config_overrides=None, progress=None, *, tick_hook=None):
    """The output byte stream of `run_all`."""
    return run_all(stim, config_overrides, progress, tick_hook=tick_hook)[0]


def run_all(stim, config_overrides=None, progress=None, *, tick_hook=None, board=None):
    """(out, (display, marks)): the output byte stream (frames, extended frames, raw records as
    configured) that the firmware produces for `stim` under the runtimes' board configuration
    plus the overrides, and what it sends to the screen's UART (model/display.py; b"" with the
    display off) with FirmwareRun.display_marks. board: the image's board (f411/boards.py) whose
    wiring decides whether there is a screen (None: the firmware's default board).

    progress(k, n): every 2000 ticks and at the end. tick_hook(k, model): called at tick k
    before the navigator's step (tests use it to perturb the model)."""
    values = board_config.run_values(stim, config_overrides)
    cfg = config.decode(board_config.to_bytes(values))  # what the board reads from flash
    install_machine()  # the virtual clock pps_isr stamps from (time.set_us)
    loop = _Loop(stim, cfg, _page(cfg, _firmware()[1], board))
    n = len(stim)
    for k in range(n):
        loop.interval(k)
        loop.tick(k, tick_hook)
        if progress and k % 2000 == 1999:
            progress(k + 1, n)
    frames = frame_bytes(loop.t, cfg)
    if progress:
        progress(n, n)
    shown = _screen(loop.page, loop.views, frames)
    if not loop.extra:
        return frames.tobytes(), shown
    return _interleave(frames, loop.frame_ticks, loop.extra, n), shown


class _Loop:
    """The firmware's loop over a stimulus: the app's state between ticks (the receive ring,
    the fix, the PPS checks, the counters) and what it sent so far ("t": the frames' fields,
    "extra": tick -> bytes sent after that tick's frame, "views": the status page's turns)."""

    def __init__(self, stim, cfg, page):
        self.cfg = cfg
        self.cfg_status = config.OK if cfg.validate() is None else config.INVALID
        self.model = NavModel(cfg.nav_config())
        self.g = Nmea(need_speed=cfg.gnss_need_speed)  # as app.App builds its parser
        self.tick_us = stim.tick_us
        self.t0 = first_tick_us(stim.tick_us)
        imu = _imu_inputs(stim)
        self.gyro_l, self.accel_l = imu["gyro_l"], imu["accel_l"]
        self.sat_l, self.fresh_l = imu["sat_l"], imu["fresh_l"]
        self.pps_before = stim.pps_before_us.tolist()
        self.offs = stim.uart_offsets.tolist()
        self.ub = stim.uart_bytes
        self.g_regs = imu["gyro_regs"].tobytes()
        self.a_regs = imu["accel_regs"].tobytes()
        # app.service: a stalled tick (an injected fault) runs no loop; the next one counts the
        # ticks it missed, so the tick count stays k + 1 and only the stalled ticks' frames are
        # lost
        self.stalled_l = stim.stalled.tolist()
        n = len(stim)
        out_every = cfg.output_every_ticks
        self.frame_ticks = np.flatnonzero(((np.arange(n) + 1) % out_every == 0) & ~stim.stalled)
        self.t = _frame_table(imu, self.frame_ticks)
        self.extra = {}  # tick -> bytes sent after that tick's frame (extended frame, raw record)
        self.page = page  # the screen's status page (None: off, or no UART)
        self.views = []  # (ticks, display.View without its frame, the last frame's index)
        self.last_ext = None
        self.ring = bytearray()
        self.fix = _Fix()
        self.counter = 0
        # the app's PPS, late-epoch and NMEA checks
        self.pps = {"last": 0, "bad": 0, "edge_us": 0, "edge_s": -1, "late_bad": 0, "nmea": 0,
                    "nmea_bad": 0, "edges_ok": 0, "overdue": 0x3FFFFFFF, "step_s": 0,
                    "step_n": 0, "step_bad": 0}  # fmt: skip
        self.j = 0  # frames so far
        self.lost = 0  # ticks stalled since the last one run
        self.last = ([0, 0, 0], [0, 0, 0], False, False)  # the last sample read
        self.overruns = 0  # app.overruns, and its value at the last extended frame
        self.ext_overruns = 0

    def interval(self, k):
        """The interval before tick k: bytes arrive in the ring, the PPS edge fires."""
        a, b = self.offs[k], self.offs[k + 1]
        if b > a:
            chunk = self.ub[a:b][: max(_firmware()[1].GNSS_RXBUF - len(self.ring), 0)]
            self.ring += chunk
        t_k = self.t0 + k * self.tick_us
        if self.pps_before[k] >= 0:
            time.set_us(t_k - self.pps_before[k])
            self.g.pps_isr(None)
        time.set_us(t_k)

    def tick(self, k, tick_hook):
        """Tick k (none if stalled): IMU read, GNSS poll, fix, navigator, then what it sends."""
        if self.stalled_l[k]:
            self.lost += 1
            return
        fw_app = _firmware()[0]
        model, g = self.model, self.g
        # ticks_us() during the tick (the loop takes no time)
        now = (self.t0 + k * self.tick_us) % TICKS_PERIOD
        if self.lost:  # app._catch_up: the navigator steps through the missed ticks on the
            self.overruns += self.lost  # last sample read (the driver's zeros before the first)
            for _ in range(min(self.lost, fw_app._CATCH_UP_MAX)):
                model.imu_raw(*self.last, repeat=True)
            self.lost = 0
        self.last = (self.gyro_l[k], self.accel_l[k], self.sat_l[k], self.fresh_l[k])
        # tick k: IMU read, GNSS poll, fix, navigator
        # an epoch completed in an earlier tick first, then this tick's bytes (app.service)
        if g.epoch_take():
            deliver_fix(g, model, self.fix, self.cfg.gnss_hdop_max, now, self.pps, k + 1)
        rx = _uart_read(self.ring, g)
        if tick_hook is not None:
            tick_hook(k, model)
        model.imu_raw(self.gyro_l[k], self.accel_l[k], self.sat_l[k], self.fresh_l[k])
        self._send(k, now, rx)

    def _send(self, k, now, rx):
        """What tick k sends: its frame's fields, an extended frame, a raw record; the status
        page's view at its turn."""
        cfg, g, ticks = self.cfg, self.g, k + 1
        parts = []
        if ticks % cfg.output_every_ticks == 0:
            _frame_fields(self.t, self.j, g, self.pps, ticks, self.fix, self.model)
            self.j += 1
            self.counter = (self.counter + 1) & 0xFF
        if cfg.ext_every_ticks and ticks % cfg.ext_every_ticks == 0:
            causes = _app_causes(self.cfg_status, g, self.pps, ticks)
            if self.overruns != self.ext_overruns:
                self.ext_overruns = self.overruns
                causes |= _firmware()[0].CAUSE_OVERRUN
            self.last_ext = _ext_bytes(self.counter, self.model, self.cfg_status, causes,
                                       self.fix, self.sat_l[k], self.overruns)  # fmt: skip
            parts.append(self.last_ext)
        if cfg.raw_record:
            parts.append(
                records.encode_raw(
                    self.counter,
                    now,
                    g.pps_us,
                    self.g_regs[6 * k : 6 * k + 6],
                    self.a_regs[6 * k : 6 * k + 6],
                    self.sat_l[k],
                    rx,
                )
            )
        if parts:
            self.extra[k] = b"".join(parts)
        if self.page is not None and ticks % display.SLOT == display.PHASE:
            self.views.append((ticks, _view(self.model, self.fix, g, self.last_ext), self.j - 1))


def _imu_inputs(stim):
    """What the driver reads and decodes, vectorised over the ticks: the registers ("gyro_regs",
    "accel_regs"), the counts ("gyro", "accel": (N, 3) int64) and, as lists per tick, the
    counts, the driver's `saturated` and an accel new-data bit ("gyro_l", "accel_l", "sat_l",
    "fresh_l")."""
    bmi055 = _firmware()[3]
    # what the driver reads: the registers, or the bus' idle 0xFF where the IMU does not answer
    # (an injected fault: stimulus.imu_silent)
    gyro_regs = stim.gyro_regs.copy()
    accel_regs = stim.accel_regs.copy()
    gyro_regs[stim.imu_silent] = 0xFF
    accel_regs[stim.imu_silent] = 0xFF
    gyro = stim_mod.gyro_counts(gyro_regs).astype(np.int64)
    accel = stim_mod.accel_counts(accel_regs).astype(np.int64)
    gyro_sat = (gyro >= bmi055.GYRO_SAT_HI) | (gyro <= bmi055.GYRO_SAT_LO)
    accel_sat = (accel >= bmi055.ACCEL_SAT_HI) | (accel <= bmi055.ACCEL_SAT_LO)
    sat = gyro_sat.any(axis=1) | accel_sat.any(axis=1)  # the driver's `saturated`
    fresh = (accel_regs[:, 0:6:2] & 1).any(axis=1)  # an accel new_data bit (status 6-8)
    return {
        "gyro_regs": gyro_regs,
        "accel_regs": accel_regs,
        "gyro": gyro,
        "accel": accel,
        "gyro_l": gyro.tolist(),
        "accel_l": accel.tolist(),
        "sat_l": sat.tolist(),
        "fresh_l": fresh.tolist(),
    }


def _frame_table(imu, frame_ticks):
    """The per-frame arrays `frame_bytes` packs, for the frames at ticks frame_ticks: the
    sensor counts filled in, the rest zero until the loop sets them (_frame_fields)."""
    nf = len(frame_ticks)
    return {
        "counter": np.arange(nf) & 0xFF,
        "gyro": imu["gyro"][frame_ticks],
        "accel": imu["accel"][frame_ticks],
        "pps": np.zeros(nf, np.uint8),
        "gga": np.zeros(nf, np.uint8),
        "valid": np.zeros(nf, np.uint8),
        "lat_e7": np.zeros(nf, np.int64),
        "lon_e7": np.zeros(nf, np.int64),
        "height_dm": np.zeros(nf, np.int64),
        "state": np.zeros(nf, np.int64),
        "c_bn": np.zeros((nf, 3, 3), F32),
        "v_n": np.zeros((nf, 3), F32),
        "p_n": np.zeros((nf, 3), F32),
    }


def _uart_read(ring, g):
    """The loop's GNSS poll: at most app._RX_LEN bytes taken from the receive ring and fed to
    the parser; the bytes read (b"": none)."""
    if not ring:
        return b""
    m = min(len(ring), _firmware()[0]._RX_LEN)
    rx = bytes(ring[:m])
    del ring[:m]
    g.feed(rx, m)
    return rx


def _frame_fields(t, j, g, pps, ticks, fix, model):
    """Frame j's fields at a frame tick: the PPS and GGA flags taken (an edge's flag runs
    app._pps_seen), the fix, the navigator's state and solution."""
    t["pps"][j] = g.pps_flag_take()
    if t["pps"][j]:
        _pps_seen(g, pps, ticks)
    t["gga"][j] = g.gga_flag_take()
    t["valid"][j] = fix.valid
    t["lat_e7"][j] = fix.lat_e7
    t["lon_e7"][j] = fix.lon_e7
    t["height_dm"][j] = fix.height_dm
    t["state"][j] = model.state
    t["c_bn"][j] = model.ins.c_bn
    t["v_n"][j] = model.ins.v_n
    t["p_n"][j] = model.ins.p_n


def _app_causes(cfg_status, g, pps, ticks):
    """app._send_ext: the app's own causes at an extended frame, each a warning (the overrun
    cause aside, which the loop adds)."""
    fw_app = _firmware()[0]
    causes = 0
    if cfg_status != config.OK:
        causes = fw_app.CAUSE_CONFIG
    if ticks >= pps["overdue"]:  # no epoch yet after the last edge? (app._send_ext)
        pps["overdue"] = fw_app._NEVER
        if g.epoch_pps_us != pps["last"]:
            pps["late_bad"] = ticks + fw_app._SECOND_TICKS
            pps["edges_ok"] = 0
    if ticks < pps["nmea_bad"]:
        causes |= fw_app.CAUSE_NMEA
    if ticks < pps["bad"]:
        causes |= fw_app.CAUSE_PPS
    if ticks < pps["late_bad"]:
        causes |= fw_app.CAUSE_GNSS_LATE
    if ticks < pps["step_bad"]:
        causes |= fw_app.CAUSE_GNSS_CLOCK
    return causes


def _ext_bytes(counter, model, cfg_status, causes, fix, sat, overruns):
    """The extended frame app._send_ext sends: the app's causes make the health at least a
    warning and join the navigator's; the flags: fix valid, still, saturated."""
    health = model.health
    if causes and health == 0:
        health = 1
    causes |= model.causes
    flags = fix.valid | (2 if model.still else 0) | (4 if sat else 0)
    return ext_frame(counter, health, model.state, cfg_status, flags, model, causes, overruns)


def _view(model, fix, g, last_ext):
    """The status page's view at a turn, without its frame (set once the frames are packed)."""
    return display.View(model.state, fix.valid, fix.lat_e7, fix.lon_e7, fix.height_dm,
                        g.epoch_quality, g.epoch_nsat, g.epoch_hdop_x100, b"",
                        last_ext, model.health, model.causes)  # fmt: skip


def _screen(page, views, frames):
    """(bytes, marks): what the status page sends over the run's turns (views), and (tick,
    end offset) after each tick that wrote; (b"", []) without a page."""
    if page is None:
        return b"", []
    page.start()
    marks = [(-1, len(page.out))]
    for ticks, view, fi in views:
        view.frame = frames[fi].tobytes() if fi >= 0 else bytes(52)
        page.turn(ticks, view)
        if len(page.out) > marks[-1][1]:
            marks.append((ticks - 1, len(page.out)))
    return bytes(page.out), marks


def _interleave(frames, frame_ticks, extra, n):
    """The output stream: each tick's frame (if it had one), then its extra bytes."""
    out = bytearray()
    is_frame = np.zeros(n, bool)
    is_frame[frame_ticks] = True
    fi = 0
    for k in range(n):
        if is_frame[k]:
            out += frames[fi].tobytes()
            fi += 1
        if k in extra:
            out += extra[k]
    return bytes(out)


def _page(cfg, fw_board, board=None):
    """The status page app.App makes: display on, a UART for it, a size that fits."""
    if board is None:
        uart = fw_board.PINS["display_uart"]
    else:
        from host_emulator.f411 import boards

        uart = boards.BOARDS[board].display_uart
    if not cfg.display or uart is None:
        return None
    if display.font_for(cfg.display_w, cfg.display_h) == 0:
        return None
    return display.Page(cfg)
