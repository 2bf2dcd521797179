"""The live view: what the monitor knows about the board (last frame, last extended frame,
rates, error counts), drawn as a block of lines redrawn in place with plain ANSI escapes on a
terminal, or as one line per second when stdout is not a terminal; and the final summary."""

import collections
import math

from host_emulator.proto import records
from tools.monitor.export import sigmas

NAV_STATES = {1: "ALIGNING", 2: "NAVIGATING"}
HEALTH = {0: "normal", 1: "WARNING", 2: "FAULT"}
CONFIG_STATUS = {0: "ok", 1: "missing (defaults)", 2: "CORRUPT (defaults)", 3: "INVALID (defaults)"}


def nav_state_name(n):
    return NAV_STATES.get(n, f"state {n}")


class Status:
    """What the view shows, updated from the decoded records."""

    WINDOW_S = 2.0  # rates over the last 2 s

    def __init__(self, source, baud=None):
        self.source = source
        self.baud = baud
        self.frame = None  # last frame's fields
        self.frame_t = None  # its board time (s)
        self.first_t = None
        self.ext = None  # last extended frame's fields
        self.fix = None  # last frame with a GGA sentence and a valid fix
        self.fix_t = None
        self.n_frames = 0  # frames shown (a file with --seconds: those before the limit)
        self._samples = collections.deque()  # (wall s, frames, ext, bytes)

    def on_frame(self, t, f):
        self.n_frames += 1
        self.frame = f
        self.frame_t = t
        if self.first_t is None:
            self.first_t = t
        if f["gnss_valid"] and f["gga"]:
            self.fix = f
            self.fix_t = t

    def on_ext(self, e):
        self.ext = e

    def sample(self, now, counts):
        s = self._samples
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


def error_line(c):
    return (
        f"checksum failures {c['bad_checksum']}  CRC failures {c['bad_crc']}  "
        f"skipped bytes {c['skipped_bytes']}  dropped frames (counter gaps) {c['dropped_frames']}"
        + (
            f"  + {c['wrap_losses']} lost in whole counter wraps (extended-frame ticks)"
            if c.get("wrap_losses")
            else ""
        )
    )


def render(st, counts, elapsed_s, live=True):
    """The live view's lines (live=False: a whole file, rates are its means over board time)."""
    src = st.source + (f" @ {st.baud} baud" if st.baud else "")
    if live:
        lines = [f"INS monitor  {src}  {elapsed_s:7.1f} s   (Ctrl-C to stop)"]
        fr, er, br = st.rates()
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
        state = nav_state_name(f["nav_state"])
        extra = ""
        if e is not None:
            extra = (
                f"   health {e['health']} {HEALTH.get(e['health'], '?')}"
                f"   config {CONFIG_STATUS.get(e['config_status'], e['config_status'])}"
                f"   board tick {e['tick']}"
            )
        lines.append(f"state      {state:<11}{extra}")
        if e is not None and e.get("causes"):
            lines.append(f"causes     {' '.join(records.cause_names(e['causes']))}")
        gnss = "valid" if f["gnss_valid"] else "NO FIX"
        if st.fix is not None:
            age = st.frame_t - st.fix_t
            fx = st.fix
            gnss += (
                f"   last fix {_latlon(fx['lat_e7'], fx['lon_e7'])}  {fx['height_m']:.1f} m"
                f"   ({age:.1f} s ago)"
            )
        else:
            gnss += "   no fix received yet"
        lines.append(f"GNSS       {gnss}")
        pe, pn, pu = f["pos_enu_m"]
        ins = _ins_latlon(e, f)
        lines.append(
            f"position   E {pe:10.2f}  N {pn:10.2f}  U {pu:7.1f} m"
            + (f"   INS {ins} (ellipsoidal)" if ins else "")
        )
        ve, vn, vu = f["vel_enu_m_s"]
        sp = math.hypot(ve, vn)
        lines.append(
            f"velocity   E {ve:7.2f}  N {vn:7.2f}  U {vu:7.2f} m/s   speed {sp:6.2f} m/s"
            f" ({sp * 3.6:.1f} km/h)"
        )
        lines.append(
            f"attitude   yaw {f['yaw_deg']:7.2f}  pitch {f['pitch_deg']:6.2f}  "
            f"roll {f['roll_deg']:6.2f} deg"
        )
        if e is not None:
            s = sigmas(e)
            lines.append(
                "sigma      pos " + "/".join(_f(x, "{:.2f}") for x in s["pos"]) + " m   vel "
                + "/".join(_f(x, "{:.3f}") for x in s["vel"]) + " m/s   att "
                + "/".join(_f(x, "{:.2f}") for x in s["att_deg"]) + " deg (E/N/U)"
            )  # fmt: skip
        else:
            lines.append("sigma      - (no extended frame yet)")
    lines.append(
        f"rates      {_f(fr, '{:.1f}')} frames/s   {_f(er, '{:.1f}')} ext/s   "
        f"{_f(br, '{:.0f}')} B/s   ({counts['frames']} frames, {counts['ext']} ext, "
        f"{counts['raw']} raw, {counts['bytes']} bytes)"
    )
    lines.append(f"errors     {error_line(counts)}")
    return lines


def one_line(st, counts, elapsed_s):
    """The view as one line (stdout not a terminal)."""
    fr, _er, br = st.rates()
    head = f"{elapsed_s:6.1f} s  {_f(fr, '{:.1f}')} Hz  {_f(br, '{:.0f}')} B/s"
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
        if st.ext is not None:
            body += f" health={st.ext['health']}"
            if st.ext.get("causes"):
                body += f" ({','.join(records.cause_names(st.ext['causes']))})"
    c = counts
    errs = (
        f"checksum={c['bad_checksum']} crc={c['bad_crc']} skipped={c['skipped_bytes']} "
        f"dropped={c['dropped_frames']}"
    )
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
