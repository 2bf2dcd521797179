"""The receiver's byte stream: NMEA-0183 sentences for each simulated epoch, sent at the UART's
baud rate, some of them damaged.

Per epoch the receiver prints `model.sentences` in order (default GGA GSA RMC, as MTK chips
do) with talker `model.talker`, starting at the epoch's t_avail_s (latency after the fix time)
or when the previous epoch's bytes have gone out, whichever is later. Each byte takes 10 bit
times (8N1) and counts as arrived at the end of its stop bit.

Fields: time hhmmss.ss (UTC = model.utc_start + t), latitude/longitude as ddmm.mmmmmm with
six minute decimals (the 1e-7 deg fix converts exactly: frac_e7 * 6 = minutes * 1e6), GGA
altitude above mean sea level = ellipsoidal height - geoid_sep_m with 3 decimals, HDOP with 2,
RMC speed in knots with 3 decimals and course with 2 (empty below the course threshold; both
empty when the epoch's speed is NaN: no velocity reported);
RMC mode A (D while quality 2). A no-fix epoch prints an empty GGA (quality 0) and RMC
status V, as receivers do. GSA lists `nsat` satellite ids, PDOP/HDOP/VDOP.

Damage: with probability model.corrupt_per_sentence a sentence has one byte between '$' and
'*' replaced by a different printable one (the checksum then fails, as after line noise).
Epoch data that do not fit the baud rate (bytes per epoch x rate > baud / 10) raise
ValueError: a real receiver would drop sentences; pick a faster baud.
"""

import datetime

import numpy as np

_STREAM_NMEA = 0x4E4D4541
KNOTS_PER_M_S = 3600.0 / 1852.0


def checksum(body):
    """XOR of the characters between '$' and '*'."""
    c = 0
    for ch in body.encode("ascii"):
        c ^= ch
    return c


def sentence(body):
    return f"${body}*{checksum(body):02X}\r\n".encode("ascii")


def _lat(lat_e7):
    a = abs(int(lat_e7))
    deg, frac = divmod(a, 10_000_000)
    mn = frac * 6  # minutes x 1e6
    return f"{deg:02d}{mn // 1_000_000:02d}.{mn % 1_000_000:06d}", "N" if lat_e7 >= 0 else "S"


def _lon(lon_e7):
    a = abs(int(lon_e7))
    deg, frac = divmod(a, 10_000_000)
    mn = frac * 6
    return f"{deg:03d}{mn // 1_000_000:02d}.{mn % 1_000_000:06d}", "E" if lon_e7 >= 0 else "W"


def _utc(start, t_s):
    """(hhmmss.ss, ddmmyy) at t_s seconds after start."""
    cs = int(round(t_s * 100))
    t = start + datetime.timedelta(seconds=cs // 100)
    return f"{t:%H%M%S}.{cs % 100:02d}", f"{t:%d%m%y}"


def _speed_course(fx):
    """RMC/VTG speed (knots) and course fields; both empty when the speed is NaN (a receiver
    configured not to report velocity: the replay of position-only data)."""
    if np.isnan(fx.speed_m_s):
        return "", ""
    kn = f"{fx.speed_m_s * KNOTS_PER_M_S:.3f}"
    return kn, "" if np.isnan(fx.course_deg) else f"{fx.course_deg:.2f}"


def epoch_sentences(fx, model, start):
    """The sentences (bytes) of one epoch (a GnssFix)."""
    hms, dmy = _utc(start, fx.t_fix_s)
    tk = model.talker
    ok = fx.quality > 0
    out = []
    for name in model.sentences:
        if name == "GGA":
            if ok:
                lat, ns = _lat(fx.lat_e7)
                lon, ew = _lon(fx.lon_e7)
                msl = fx.h_m - model.geoid_sep_m
                body = (
                    f"{tk}GGA,{hms},{lat},{ns},{lon},{ew},{fx.quality},{fx.nsat:02d},"
                    f"{fx.hdop:.2f},{msl:.3f},M,{model.geoid_sep_m:.1f},M,,"
                )
            else:
                body = f"{tk}GGA,{hms},,,,,0,{fx.nsat:02d},,,M,,M,,"
        elif name == "RMC":
            if ok:
                lat, ns = _lat(fx.lat_e7)
                lon, ew = _lon(fx.lon_e7)
                kn, course = _speed_course(fx)
                mode = "D" if fx.quality == 2 else "A"
                body = f"{tk}RMC,{hms},A,{lat},{ns},{lon},{ew},{kn},{course},{dmy},,,{mode}"
            else:
                body = f"{tk}RMC,{hms},V,,,,,,,{dmy},,,N"
        elif name == "VTG":
            if ok:
                kn, course = _speed_course(fx)
                kmh = "" if np.isnan(fx.speed_m_s) else f"{fx.speed_m_s * 3.6:.3f}"
                body = f"{tk}VTG,{course},T,,M,{kn},N,{kmh},K,A"
            else:
                body = f"{tk}VTG,,T,,M,,N,,K,N"
        elif name == "GSA":
            n = int(fx.nsat) if ok else 0
            ids = [f"{i + 1:02d}" for i in range(min(n, 12))] + [""] * (12 - min(n, 12))
            if ok:
                dops = f"{1.6 * fx.hdop:.2f},{fx.hdop:.2f},{1.3 * fx.hdop:.2f}"
            else:
                dops = ",,"
            body = f"{tk}GSA,A,{3 if ok else 1},{','.join(ids)},{dops}"
        else:
            raise ValueError(f"unknown sentence type {name!r} (GGA, RMC, VTG, GSA)")
        out.append(sentence(body))
    return out


def _damage(rng, s):
    """One byte between '$' and '*' replaced by a different printable character."""
    star = s.index(b"*")
    i = int(rng.integers(1, star))
    b = bytearray(s)
    new = int(rng.integers(0x20, 0x7E))
    b[i] = new if new != b[i] else new + 1
    return bytes(b)


def stream(gnss, seed=0):
    """All epochs as (start_s, bytes) with start the time the first byte begins; plus the
    number of damaged sentences. Raises ValueError if the epochs do not fit the baud rate."""
    model = gnss.model
    start = datetime.datetime.fromisoformat(model.utc_start)
    rng = np.random.default_rng([seed, _STREAM_NMEA])
    byte_s = 10.0 / model.baud
    epochs = []
    damaged = 0
    free_at = 0.0
    for fx in gnss:
        parts = epoch_sentences(fx, model, start)
        for j, s in enumerate(parts):
            if rng.random() < model.corrupt_per_sentence:
                parts[j] = _damage(rng, s)
                damaged += 1
        data = b"".join(parts)
        if len(data) * byte_s * model.rate_hz > 1.0:
            raise ValueError(
                f"{len(data)} bytes per epoch at {model.rate_hz:g} Hz do not fit {model.baud} "
                f"baud ({model.baud // 10} bytes/s): choose a faster baud or fewer sentences"
            )
        t0 = max(fx.t_avail_s, free_at)
        free_at = t0 + len(data) * byte_s
        epochs.append((t0, data))
    return epochs, damaged


def per_tick(epochs, baud, ticks, tick_s):
    """Spread the epochs' bytes over ticks: tick k gets the bytes whose stop bit ends in
    ((k-1) tick_s, k tick_s]. Returns (offsets (ticks+1,), bytes); bytes after the last tick
    are dropped (the run ended)."""
    if not epochs:
        return np.zeros(ticks + 1, np.int64), b""
    byte_s = 10.0 / baud
    data = b"".join(d for _, d in epochs)
    arrive = np.concatenate([t0 + byte_s * np.arange(1, len(d) + 1) for t0, d in epochs])
    # tick index k = ceil(arrive / tick_s), computed in integer microseconds-free form
    k = np.ceil(arrive / tick_s - 1e-9).astype(np.int64)
    keep = k < ticks
    k = k[keep]
    data = data[: int(keep.sum())]
    counts = np.bincount(k, minlength=ticks)[:ticks]
    offs = np.concatenate([[0], np.cumsum(counts)])
    return offs, data
