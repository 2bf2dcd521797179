"""Walking a recorded stream: from the board's first tick, tick by tick, every record where
the firmware sends it, up to the end or the first gap; the result is a `Recording`.

The stream. From the firmware's start, tick k (app.ticks = T = k + 1) sends, in this order: the
52-byte frame if T % output_every_ticks == 0 (counter (T // output_every_ticks - 1) & 0xFF),
the extended frame if T % ext_every_ticks == 0 (counter (T // output_every_ticks) & 0xFF, tick
field T), the raw-input record (same counter). The replay starts at the board's first tick,
found as the first group that chains like tick 0 and whose first extended frame carries tick T
(bytes before it, e.g. the end of an earlier run, are skipped). A record that is missing,
damaged (its checksum or CRC fails) or out of sequence is a gap: the firmware's state after it
cannot be known, so `parse` raises SessionError naming the byte offset and tick, or with
`until_gap` keeps the ticks before it. Stray bytes between records that still chain (line
noise) are counted, not an error. The last tick, if cut short by the end of the capture, is
left out.
"""

import struct
from dataclasses import dataclass, field

import numpy as np

from common import firmware_env
from common.proto import config as board_config
from common.proto import records
from common.proto import stimulus as stim_mod
from common.proto.frame import FRAME_TYPE
from common.proto.records import EXT_TYPE, RAW_TYPE
from common.proto.session_file import SessionError
from common.proto.stream import StreamDecoder

TICK_US = stim_mod.TICK_US
TICK_MASK = 0x3FFFFFFF  # the extended frame's tick field wraps here
KIND_NAME = {FRAME_TYPE: "frame", EXT_TYPE: "extended frame", RAW_TYPE: "raw-input record"}


def _items(data):
    """The stream split into ("rec", offset, bytes) for every valid record (proto/stream.py's
    reading) and ("junk", offset, length) for the bytes between them, in order."""
    out = []
    pos = 0
    for _, off, r in StreamDecoder().records(data, final=True):
        if off > pos:
            out.append(("junk", pos, off - pos))
        out.append(("rec", off, r))
        pos = off + len(r)
    if pos < len(data):
        out.append(("junk", pos, len(data) - pos))
    return out


def _counter(rec):
    return rec[2] if rec[1] == FRAME_TYPE else rec[3]


def _ext_tick(rec):
    return struct.unpack_from("<I", rec, records.EXT_OFFSETS["tick"])[0]


def _expected(k, every, ext_every):
    """[(type, counter)] tick k sends (app.ticks = k + 1), in order."""
    t = k + 1
    c = (t // every) & 0xFF
    exp = []
    if t % every == 0:
        exp.append((FRAME_TYPE, (c - 1) & 0xFF))
    if ext_every and t % ext_every == 0:
        exp.append((EXT_TYPE, c))
    exp.append((RAW_TYPE, c))
    return exp


def _describe(item):
    if item is None:
        return "the end of the capture"
    if item[0] == "junk":
        return f"{item[2]} undecodable bytes"
    rec = item[2]
    what = f"a {KIND_NAME[rec[1]]} with counter {_counter(rec)}"
    if rec[1] == EXT_TYPE:
        what += f" and tick {_ext_tick(rec)}"
    return what


@dataclass
class _Walk:
    groups: list  # per tick: [record bytes, ...] in stream order
    end_offset: int  # byte after the last complete tick
    stray: int  # bytes between records of the chain that belong to nothing
    stop: str | None  # why the walk stopped before the end of the stream (a gap), or None
    stop_offset: int | None = None


def _walk(items, start, every, ext_every, max_ticks=None, explain=True):
    """Follow the tick chain from items[start] as tick 0 (explain: say in the gap's message
    whether the board restarted there)."""
    groups = []
    idx = start
    stray = 0
    end_offset = items[start][1]
    k = 0
    while max_ticks is None or k < max_ticks:
        group = []
        skipped = []
        for typ, counter in _expected(k, every, ext_every):
            while idx < len(items) and items[idx][0] == "junk":
                skipped.append(items[idx])
                idx += 1
            if idx == len(items):
                return _Walk(groups, end_offset, stray, None)  # the capture ends here
            rec = items[idx][2]
            got_counter = _counter(rec)
            ok = rec[1] == typ and got_counter == counter
            if ok and typ == EXT_TYPE:
                ok = _ext_tick(rec) == (k + 1) & TICK_MASK
            if not ok:
                at = skipped[0][1] if skipped else items[idx][1]
                want = f"the {KIND_NAME[typ]} with counter {counter}"
                if typ == EXT_TYPE:
                    want += f" and tick {(k + 1) & TICK_MASK}"
                found = ", then ".join(_describe(x) for x in skipped + [items[idx]])
                if explain and _starts_run(items, idx, every, ext_every):
                    found += " (the board restarted)"
                msg = f"gap at byte {at}, tick {k} (t = {k * TICK_US * 1e-6:.3f} s): expected "
                msg += f"{want}, found {found}"
                return _Walk(groups, end_offset, stray, msg, at)
            stray += sum(x[2] for x in skipped)
            skipped = []
            group.append(rec)
            idx += 1
        groups.append(group)
        end_offset = items[idx - 1][1] + len(items[idx - 1][2])
        k += 1
    return _Walk(groups, end_offset, stray, None)


def _starts_run(items, idx, every, ext_every):
    """Whether tick 0 of a run starts at items[idx]: its first ticks chain, up to and including
    the first extended frame, whose tick field must say so."""
    need = ext_every if ext_every else 1
    w = _walk(items, idx, every, ext_every, max_ticks=need, explain=False)
    return w.stop is None and len(w.groups) == need


@dataclass(eq=False)
class Recording:
    """The replayable part of a recorded stream: one row per tick from the board's first."""

    config: dict  # the board configuration values
    start_offset: int  # byte offset of tick 0's first record in the capture
    end_offset: int  # byte after the last tick used
    t0_us: np.ndarray  # (N,) int64: the tick's start, time.ticks_us (wraps at 2**30)
    pps_us: np.ndarray  # (N,) int64: the parser's pps_us after the tick
    gyro_regs: np.ndarray  # (N, 6) uint8
    accel_regs: np.ndarray  # (N, 6) uint8
    saturated: np.ndarray  # (N,) uint8
    gnss_offsets: np.ndarray  # (N + 1,) int64 into gnss_bytes
    gnss_bytes: bytes
    records: list  # the recorded records of these ticks (bytes), in stream order
    gap: str | None = None  # the gap the ticks stop at (parse(until_gap=True))
    notes: list = field(default_factory=list)  # what was skipped or tolerated

    def __len__(self):
        return len(self.t0_us)

    def kind(self, rtype):
        """The records of one type (FRAME_TYPE, EXT_TYPE, RAW_TYPE), in order."""
        return [r for r in self.records if r[1] == rtype]

    @property
    def stream(self):
        """The recorded records of these ticks, as the board sent them."""
        return b"".join(self.records)


def _recording(values, groups, start_offset, end_offset):
    n = len(groups)
    raws = [records.decode_raw(g[-1]) for g in groups]
    t0 = np.fromiter((r["t0_us"] for r in raws), np.int64, n)
    pps = np.fromiter((r["pps_us"] for r in raws), np.int64, n)
    gyro = np.frombuffer(b"".join(r["gyro_regs"] for r in raws), np.uint8).reshape(n, 6)
    accel = np.frombuffer(b"".join(r["accel_regs"] for r in raws), np.uint8).reshape(n, 6)
    sat = np.fromiter((r["saturated"] for r in raws), np.uint8, n)
    lens = np.fromiter((len(r["gnss_bytes"]) for r in raws), np.int64, n)
    offs = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
    rec = Recording(
        config=dict(values),
        start_offset=start_offset,
        end_offset=end_offset,
        t0_us=t0,
        pps_us=pps,
        gyro_regs=gyro.copy(),
        accel_regs=accel.copy(),
        saturated=sat,
        gnss_offsets=offs,
        gnss_bytes=b"".join(r["gnss_bytes"] for r in raws),
        records=[r for g in groups for r in g],
    )
    _check_saturation(rec)
    return rec


def _check_saturation(rec):
    """The recorded saturation flag must be what the firmware's driver derives from the
    recorded registers (else the records come from another firmware, or are damaged)."""
    if not len(rec):
        return
    bmi055 = firmware_env.import_module("drivers.bmi055")
    g = stim_mod.gyro_counts(rec.gyro_regs).astype(np.int64)
    a = stim_mod.accel_counts(rec.accel_regs).astype(np.int64)
    g_sat = (g >= bmi055.GYRO_SAT_HI) | (g <= bmi055.GYRO_SAT_LO)
    a_sat = (a >= bmi055.ACCEL_SAT_HI) | (a <= bmi055.ACCEL_SAT_LO)
    derived = g_sat.any(axis=1) | a_sat.any(axis=1)
    bad = np.flatnonzero(derived.astype(np.uint8) != rec.saturated)
    if len(bad):
        k = int(bad[0])
        raise SessionError(
            f"raw-input record of tick {k}: saturation flag {int(rec.saturated[k])} but its "
            f"registers say {int(derived[k])} (recorded with another firmware version?)"
        )


def board_cfg(values):
    """The firmware's BoardConfig of a session's configuration values; SessionError if the
    firmware would not accept them."""
    try:
        return board_config.from_values(values)
    except board_config.ConfigError as e:
        raise SessionError(f"the session's configuration: {e}") from None


def rates(values):
    """(output_every_ticks, ext_every_ticks) of a session's configuration, which must send
    raw-input records."""
    cfg = board_cfg(values)
    if not cfg.raw_record:
        raise SessionError(
            "the configuration has raw_record = 0: a board configured so sends no raw-input "
            "records, and a session cannot be replayed without them (record the board with "
            "raw_record = 1, and give that configuration)"
        )
    return cfg.output_every_ticks, cfg.ext_every_ticks


def parse(data, config_values, until_gap=False, from_last_start=False):
    """The Recording in a captured stream: from the board's first tick (from_last_start: from
    its last start, when it restarted during the recording) to the end, or to the first gap.
    SessionError (naming the byte offset and tick) if the stream holds no start, or has a gap
    and until_gap is False."""
    every, ext_every = rates(config_values)
    items = _items(data)
    recs = [i for i, it in enumerate(items) if it[0] == "rec"]
    if not any(items[i][2][1] == RAW_TYPE for i in recs):
        raise SessionError(
            "nothing in the recording decodes as the board's output (wrong baud rate or "
            "wiring, or not this board's output port)"
            if not recs
            else "no raw-input records (type 0x92) in the recording, only frames: the board "
            "ran with raw_record = 0; set it to 1 in the board's configuration and record again"
        )
    first_type = _expected(0, every, ext_every)[0]
    starts = [
        i
        for i in recs
        if (items[i][2][1], _counter(items[i][2])) == first_type
        and _starts_run(items, i, every, ext_every)
    ]
    start = None
    if starts:
        start = starts[-1] if from_last_start else starts[0]
    if start is None:
        raise SessionError(
            "the recording does not hold the board's first tick: start recording before "
            "powering up or resetting the board (a replay must begin where the firmware "
            "starts); or the configuration's output_every_ticks / ext_every_ticks are not "
            "the board's"
        )
    w = _walk(items, start, every, ext_every)
    later = [items[i][1] for i in starts if i > start]
    if w.stop and not until_gap:
        hint = f"; --until-gap replays the {len(w.groups)} ticks before it"
        if later:
            hint += f", --from-last-start the run that starts at byte {items[starts[-1]][1]}"
        raise SessionError(
            f"{w.stop}. The firmware's state after a gap is unknown, so the session cannot be "
            f"replayed past it{hint}"
        )
    rec = _recording(config_values, w.groups, items[start][1], w.end_offset)
    rec.gap = w.stop
    if len(starts) > 1:
        at = ", ".join(str(items[i][1]) for i in starts)
        which = "the last" if start == starts[-1] else "the first (--from-last-start: the last)"
        rec.notes.append(
            f"the board started {len(starts)} times in the recording (at bytes {at}): "
            f"replayed from {which}"
        )
    if items[start][1]:
        rec.notes.append(f"{items[start][1]} bytes before the board's first tick skipped")
    if w.stray:
        rec.notes.append(f"{w.stray} stray bytes between records ignored (the records chain)")
    tail = len(data) - w.end_offset
    if not w.stop and tail:
        rec.notes.append(f"{tail} bytes after the last complete tick left out")
    return rec


def from_decoded(dec, config_values):
    """A Recording from a proto/stream.decode result (its raw records' counters must chain from
    the board's first tick; bytes given to `parse` are checked more closely)."""
    every, ext_every = rates(config_values)
    if not dec.raw:
        raise SessionError("no raw-input records (type 0x92) in the decoded stream")
    for k, r in enumerate(dec.raw):
        want = ((k + 1) // every) & 0xFF
        if r["counter"] != want:
            raise SessionError(
                f"gap at raw-input record {k}: counter {r['counter']}, expected {want}"
                + (" (the stream does not start at the board's first tick)" if k == 0 else "")
            )
    raws = [
        records.encode_raw(
            r["counter"],
            r["t0_us"],
            r["pps_us"],
            r["gyro_regs"],
            r["accel_regs"],
            r["saturated"],
            r["gnss_bytes"],
        )  # fmt: skip
        for r in dec.raw
    ]
    groups = []
    for k, r in enumerate(dec.raw):
        fi = r.get("frame_index", -1)
        has_frame = (k + 1) % every == 0 and 0 <= fi < len(dec.frames)
        groups.append(([dec.frames[fi]["raw"]] if has_frame else []) + [raws[k]])
    rec = _recording(config_values, groups, 0, 0)
    if ext_every:
        rec.notes.append("built from decoded records: the extended frames are not kept")
    return rec
