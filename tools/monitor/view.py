"""The live view: what the monitor knows about the board (last frame, last extended frame,
rates, error counts), drawn as a block of lines redrawn in place with plain ANSI escapes on a
terminal, or as one line per second when stdout is not a terminal; and the final summary."""

import collections
import math

from common.proto import records
from tools.monitor import nmea
from tools.monitor.export import sigmas

NAV_STATES = {1: "ALIGNING", 2: "NAVIGATING"}
HEALTH = {0: "normal", 1: "WARNING", 2: "FAULT"}
CONFIG_STATUS = {0: "ok", 1: "missing (defaults)", 2: "CORRUPT (defaults)", 3: "INVALID (defaults)"}


def nav_state_name(n):
    return NAV_STATES.get(n, f"state {n}")


class Status:
    """What the view shows, updated from the decoded records."""

    WINDOW_S = 2.0  # rates over the last 2 s

    def __init__(self, source, baud=None, recorder=None):
        self.source = source
        self.baud = baud
        self.recorder = recorder  # the --record session file (.path, .n bytes, .failed)
        self.receiver = nmea.Receiver()  # GGA/RMC from the raw-input records' GNSS bytes
        self.n_raw = 0
        self.frame = None  # last frame's fields
        self.frame_t = None  # its board time (s)
        self.first_t = None
        self.ext = None  # last extended frame's fields
        self.fix = None  # last frame with a GGA sentence and a valid fix
        self.fix_t = None
        self.n_frames = 0  # frames shown (a file with --seconds: those before the limit)
        self._samples = collections.deque()  # (wall s, frames, ext, bytes)
        self.last_frame_wall = None  # wall time (s) when the frame count last grew
        self.run_start_t = None  # capture time the board's current run began (its first
        # frame seen, or the last frame before its restart)
        self.note = None  # the newest warning, shown in the live view

    def on_frame(self, t, f):
        self.n_frames += 1
        self.frame = f
        self.frame_t = t
        if self.first_t is None:
            self.first_t = self.run_start_t = t
        if f["gnss_valid"] and f["gga"]:
            self.fix = f
            self.fix_t = t

    def on_ext(self, e):
        self.ext = e

    def on_raw(self, r):
        self.n_raw += 1
        self.receiver.feed(r["gnss_bytes"])

    def on_restart(self, t_s):
        """The board restarted after the frame at capture time t_s: the board time its run
        before lasted (s; from the first frame seen or from the board's start), and a new run
        from there."""
        run_s = t_s - (self.run_start_t if self.run_start_t is not None else t_s)
        self.run_start_t = t_s
        self.fix = None
        return run_s

    def silent_s(self, now):
        """Seconds since a frame last arrived (None before the first or without `now`)."""
        if now is None or self.last_frame_wall is None:
            return None
        return now - self.last_frame_wall

    def sample(self, now, counts):
        s = self._samples
        if not s or counts["frames"] > s[-1][1]:
            if counts["frames"]:
                self.last_frame_wall = now
        s.append((now, counts["frames"], counts["ext"], counts["bytes"]))
        while len(s) > 2 and now - s[1][0] >= self.WINDOW_S:
            s.popleft()

    def rates(self):
        """(frames/s, extended frames/s, bytes/s) over the last few seconds (None at first)."""
        s = self._samples
        if len(s) < 2 or s[-1][0] - s[0][0] < 0.2:
            return None, None, None
        dt = s[-1][0] - s[0][0]
        return ((s[-1][i] - s[0][i]) / dt for i in (1, 2, 3))

    def mean_rates(self, counts):
        """(frames/s, extended frames/s, bytes/s) over the board time seen (a file)."""
        span = self.board_seconds()
        if span <= 0:
            return None, None, None
        return ((self.n_frames - 1) / span, counts["ext"] / span, counts["bytes"] / span)

    def board_seconds(self):
        """Board time captured: the span from the first frame seen to the last, restarts
        included (the capture's time is monotonic: CaptureClock)."""
        if self.first_t is None:
            return 0.0
        return self.frame_t - self.first_t


def _f(x, fmt):
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else fmt.format(x)


def _latlon(lat_e7, lon_e7):
    lat, lon = lat_e7 / 1e7, lon_e7 / 1e7
    return f"{abs(lat):.7f} {'N' if lat >= 0 else 'S'}  {abs(lon):.7f} {'E' if lon >= 0 else 'W'}"


def _ins_latlon(e, f):
    """Integrated position: the extended frame's origin plus the frame's local ENU position."""
    if e is None or (e["origin_lat_e7"] == 0 and e["origin_lon_e7"] == 0):
        return None
    try:
        import pymap3d

        lat, lon, h = pymap3d.enu2geodetic(
            *f["pos_enu_m"], e["origin_lat_e7"] / 1e7, e["origin_lon_e7"] / 1e7, e["origin_h_m"]
        )
    except Exception:  # noqa: BLE001 (a display nicety only)
        return None
    return f"{_latlon(round(lat * 1e7), round(lon * 1e7))}  {h:.1f} m"


def _hms(utc_ms):
    s, ms = divmod(utc_ms, 1000)
    return f"{s // 3600:02d}:{s // 60 % 60:02d}:{s % 60:02d}.{ms // 10:02d}"


def fix_utc_text(rx):
    """The receiver's UTC of its last fix ("2026-11-22 02:00:03.00"; no date without an RMC
    of that time; "-" before a fix)."""
    fx = rx.last_fix
    if fx is None or fx.utc_ms is None:
        return "-"
    date = rx.fix_date()
    return f"{date} {_hms(fx.utc_ms)}" if date else _hms(fx.utc_ms)


def receiver_line(st):
    """gpsmon's items: fix type, satellites used and HDOP of the latest GGA, the UTC of the
    last fix; "-" for what the stream does not carry, and why."""
    rx = st.receiver
    g = rx.gga
    text = (
        f"receiver   fix {nmea.fix_type(g and g.quality)}  sats {_f(g and g.n_sats, '{}')}  "
        f"HDOP {_f(g and g.hdop, '{:.2f}')}  UTC {fix_utc_text(rx)}"
    )
    if not st.n_raw:
        text += "  (needs raw_record = 1)"
    elif g is None:
        text += "  (no GGA yet)"
    return text


def recording_line(rec):
    """REC, the session file and its size in MB (1e6 bytes); a long name cut at its start so
    that the size stays on screen."""
    size = f"{rec.n / 1e6:.1f} MB" + (" STOPPED (see note)" if rec.failed else "")
    room = WIDTH - len("REC        ") - len(size) - 2
    name = str(rec.path)
    if len(name) > room:
        name = "..." + name[len(name) - room + 3 :]
    return f"REC        {name}  {size}"


def error_line(c, short=False):
    """The error counts (short: the live view's 80 columns)."""
    if short:
        text = (
            f"checksum {c['bad_checksum']}  CRC {c['bad_crc']}  skipped {c['skipped_bytes']} B  "
            f"dropped {c['dropped_frames']}"
        )
        if c.get("wrap_losses"):
            text += f" + {c['wrap_losses']} in wraps"
        return text + f"  restarts {c.get('restarts', 0)}"
    return (
        f"checksum failures {c['bad_checksum']}  CRC failures {c['bad_crc']}  "
        f"skipped bytes {c['skipped_bytes']}  dropped frames (counter gaps) {c['dropped_frames']}"
        + (
            f"  + {c['wrap_losses']} lost in whole counter wraps (extended-frame ticks)"
            if c.get("wrap_losses")
            else ""
        )
        + (f"  board restarts {c['restarts']}" if c.get("restarts") else "")
    )


WIDTH = 80  # the live view fits an 80-column terminal
STALE_S = 1.0  # no frame for this long: the view says its values are old


def _fit(line):
    return line if len(line) <= WIDTH else line[: WIDTH - 3] + "..."


def render(st, counts, elapsed_s, live=True, now=None):
    """The live view's lines, at most WIDTH characters each (live=False: a whole file, rates
    are its means over board time). now: the wall time (s), for the STALE line."""
    src = st.source + (f" @ {st.baud}" if st.baud else "")
    if live:
        lines = [f"INS monitor  {src}  {elapsed_s:.1f} s  (Ctrl-C stops)"]
        fr, er, br = st.rates()
        quiet = st.silent_s(now)
        if quiet is not None and quiet >= STALE_S:
            lines.append(f"STALE      no frames for {quiet:.1f} s: the values below are old")
        if st.recorder is not None:
            lines.append(recording_line(st.recorder))
    else:
        lines = [f"INS monitor  {src}  {elapsed_s:.2f} s of board time (end of the file)"]
        fr, er, br = st.mean_rates(counts)
    f, e = st.frame, st.ext
    if f is None:
        lines.append(
            f"waiting for frames...  {counts['bytes']} bytes received, "
            f"{counts['skipped_bytes']} not decodable"
        )
    else:
        line = f"state      {nav_state_name(f['nav_state'])}"
        if e is not None:
            cfg = CONFIG_STATUS.get(e["config_status"], e["config_status"])
            line += (
                f"  health {e['health']} {HEALTH.get(e['health'], '?')}  config {cfg}"
                f"  tick {e['tick']}"
            )
        lines.append(line)
        if e is not None and e.get("causes"):
            lines.append(f"causes     {' '.join(records.cause_names(e['causes']))}")
        if st.fix is not None:
            fx = st.fix
            lines.append(
                f"GNSS       {'valid ' if f['gnss_valid'] else 'NO FIX'}  last fix "
                f"{st.frame_t - st.fix_t:.1f} s ago  {fx['height_m']:.1f} m MSL"
            )
            lines.append(f"  fix      {_latlon(fx['lat_e7'], fx['lon_e7'])}")
        else:
            lines.append(
                f"GNSS       {'valid' if f['gnss_valid'] else 'NO FIX'}  no fix received yet"
            )
        lines.append(receiver_line(st))
        pe, pn, pu = f["pos_enu_m"]
        lines.append(f"position   E {pe:10.2f}  N {pn:10.2f}  U {pu:8.1f} m (ENU)")
        ins = _ins_latlon(e, f)
        if ins:
            lines.append(f"  INS      {ins} ellipsoidal")
        ve, vn, vu = f["vel_enu_m_s"]
        sp = math.hypot(ve, vn)
        lines.append(
            f"velocity   E {ve:6.2f}  N {vn:6.2f}  U {vu:6.2f} m/s  speed {sp:5.2f} m/s"
            f" {sp * 3.6:5.1f} km/h"
        )
        lines.append(
            f"attitude   yaw {f['yaw_deg']:7.2f}  pitch {f['pitch_deg']:6.2f}  "
            f"roll {f['roll_deg']:6.2f} deg"
        )
        if e is not None:
            sg = sigmas(e)
            lines.append(
                "sigma      pos " + "/".join(_f(x, "{:.2f}") for x in sg["pos"]) + " m  vel "
                + "/".join(_f(x, "{:.3f}") for x in sg["vel"]) + " m/s (E/N/U)"
            )  # fmt: skip
            lines.append(
                "           att " + "/".join(_f(x, "{:.2f}") for x in sg["att_deg"]) + " deg"
            )
        else:
            lines.append("sigma      - (no extended frame yet)")
    lines.append(
        f"rates      {_f(fr, '{:.1f}')} frames/s  {_f(er, '{:.1f}')} ext/s  {_f(br, '{:.0f}')} B/s"
    )
    lines.append(
        f"totals     {counts['frames']} frames  {counts['ext']} ext  {counts['raw']} raw  "
        f"{counts['bytes']} bytes"
    )
    lines.append(f"errors     {error_line(counts, short=True)}")
    if live and st.note:
        lines.append(f"note       {st.note}")
    return [_fit(x) for x in lines]


def one_line(st, counts, elapsed_s, now=None):
    """The view as one line (stdout not a terminal)."""
    fr, _er, br = st.rates()
    head = f"{elapsed_s:6.1f} s  {_f(fr, '{:.1f}')} Hz  {_f(br, '{:.0f}')} B/s"
    quiet = st.silent_s(now)
    if quiet is not None and quiet >= STALE_S:
        head += f"  STALE (no frames for {quiet:.1f} s)"
    f = st.frame
    if f is None:
        body = f"no frames yet ({counts['bytes']} bytes)"
    else:
        ve, vn, _ = f["vel_enu_m_s"]
        body = (
            f"{nav_state_name(f['nav_state'])} gnss={f['gnss_valid']} "
            f"{f['lat_e7'] / 1e7:.7f},{f['lon_e7'] / 1e7:.7f} "
            f"ENU {f['pos_enu_m'][0]:.2f},{f['pos_enu_m'][1]:.2f},{f['pos_enu_m'][2]:.1f} m "
            f"speed {math.hypot(ve, vn):.2f} m/s yaw {f['yaw_deg']:.2f}"
        )
        g = st.receiver.gga
        body += (
            f" fix {nmea.fix_type(g and g.quality)} sats {_f(g and g.n_sats, '{}')}"
            f" hdop {_f(g and g.hdop, '{:.2f}')} utc {fix_utc_text(st.receiver)}"
        )
        if st.ext is not None:
            body += f" health={st.ext['health']}"
            if st.ext.get("causes"):
                body += f" ({','.join(records.cause_names(st.ext['causes']))})"
    c = counts
    errs = (
        f"checksum={c['bad_checksum']} crc={c['bad_crc']} skipped={c['skipped_bytes']} "
        f"dropped={c['dropped_frames']} restarts={c.get('restarts', 0)}"
    )
    if st.recorder is not None:
        errs += f"  REC {st.recorder.n / 1e6:.1f} MB" + (" STOPPED" if st.recorder.failed else "")
    return f"{head}  {body}  {errs}"


def summary(st, counts, wall_s, stopped, files=()):
    """The end-of-session summary lines."""
    c = counts
    span = st.board_seconds()
    rate = (st.n_frames - 1) / span if span > 0 else None
    lines = [
        f"summary: {c['frames']} frames, {c['ext']} extended frames, {c['raw']} raw records "
        f"from {c['bytes']} bytes of {st.source} ({stopped})",
        f"  board time {span:.2f} s"
        + (f" ({rate:.1f} frames/s)" if rate else "")
        + f", wall time {wall_s:.1f} s",
        f"  errors: {error_line(c)}",
    ]
    if st.frame is not None:
        f = st.frame
        lines.append(
            f"  last frame: {nav_state_name(f['nav_state'])}, GNSS "
            f"{'valid' if f['gnss_valid'] else 'invalid'}, ENU "
            f"{f['pos_enu_m'][0]:.2f} {f['pos_enu_m'][1]:.2f} {f['pos_enu_m'][2]:.1f} m"
        )
    for desc in files:
        lines.append(f"  wrote {desc}")
    return lines
