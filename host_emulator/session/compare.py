"""A replayed session compared with its recording (eval/compare.py does the record-by-record
work): the 52-byte frames byte for byte; the extended frames byte for byte except their timing
fields (worst and mean tick us, overruns, GC runs: run time, which the emulator does not model)
and the CRC that covers them; the raw records except their two absolute times (the emulator's
clock is not the board's) and CRC. On a runtime that is not bit-exact (mpy_unix: double
precision) the frames' integer fields must be equal and their attitude, velocity and position
within VM_FLOAT_STEPS steps, and only the extended frames' integer fields are compared.
"""

from dataclasses import dataclass

from common.proto import frame, records, stream
from common.proto.records import CRC_LEN, EXT_OFFSETS, RAW_OFFSETS
from host_emulator.eval.compare import EXT, FRAME, RAW, KindResult, compare_kind
from host_emulator.session.walk import TICK_US

LABELS = ("recorded", "replayed")
RAW_TIME_FIELDS = stream.RAW_CLOCK_FIELDS  # the board's own clock
VM_FLOAT_STEPS = 2  # mpy_unix: frame attitude/velocity/position within this many steps
_TIMING = slice(EXT_OFFSETS["worst_tick_us"], EXT_OFFSETS["p_diag"])
_EXT_INT_TAIL = slice(EXT_OFFSETS["origin_lat_e7"], EXT_OFFSETS["origin_h_m"])  # lat, lon, tick
_NAV_FLOATS_AT = frame.OFFSETS[frame.NAV_FLOAT_FIELDS[0]]
_NAV_FLOAT_INDEX = [frame.NAMES.index(n) for n in frame.NAV_FLOAT_FIELDS]


@dataclass
class Comparison:
    frame: KindResult
    ext: KindResult
    raw: KindResult
    tick_us: int = TICK_US
    timing_differs: int = 0  # extended frames whose (excluded) timing fields differ
    exact: bool = True  # False: a runtime that is not bit-exact, compared to a tolerance
    stream_error: str | None = None

    @property
    def identical(self):
        return (
            self.stream_error is None
            and self.frame.identical
            and self.ext.identical
            and self.raw.identical
        )

    def summary(self):
        lines = []
        if self.stream_error:
            lines.append("stream: " + self.stream_error)
        for k in (self.frame, self.ext, self.raw):
            if k.counts == (0, 0):
                continue
            line = k.line(self.tick_us, "identical" if self.exact else "equal")
            if k.kind == FRAME and k.first == 0:
                if {f.name for f in k.fields} & set(frame.SENSOR_FIELDS):
                    line += " (the configuration's sensor ranges are not the board's?)"
            if k.excluded:
                line += f" [not compared: {k.excluded}]"
            lines.append(line)
        if self.timing_differs:
            lines.append(
                f"extended frames: timing fields differ in {self.timing_differs} (expected "
                "for a board: the emulator does not model run time)"
            )
        return "\n".join(lines)


def _ext_key(rec, exact):
    head = rec[: _TIMING.start]
    return head + (rec[_TIMING.stop : -CRC_LEN] if exact else rec[_EXT_INT_TAIL])


def _raw_key(rec):
    return rec[: RAW_OFFSETS["t0_us"]] + rec[RAW_OFFSETS["gyro_regs"] : -CRC_LEN]


def _frame_ok(a, b, exact):
    if a == b:
        return True
    if exact or a[:_NAV_FLOATS_AT] != b[:_NAV_FLOATS_AT]:
        return False
    va = frame.STRUCT.unpack(a)
    vb = frame.STRUCT.unpack(b)
    return all(abs(va[i] - vb[i]) <= VM_FLOAT_STEPS for i in _NAV_FLOAT_INDEX)


def compare(recorded, replayed, output_every_ticks=1, ext_every_ticks=20, exact=True):
    """Compare two output streams (bytes of records: the recorded one as `Recording.stream`
    gives it, the replayed one as the emulator wrote it): a Comparison naming the first
    differing record of each kind, its tick and fields. exact=False: the tolerance of a
    runtime that is not bit-exact (module docstring)."""
    rec_f, rec_e, rec_r, rec_err = stream.split(recorded)
    rep_f, rep_e, rep_r, rep_err = stream.split(replayed)
    err = "; ".join(f"{s}: {e}" for s, e in zip(LABELS, (rec_err, rep_err), strict=True) if e)
    ext_skip = {*records.EXT_TIMING_FIELDS, "crc32", *(() if exact else records.EXT_FLOAT_FIELDS)}
    f_skip = set() if exact else {*frame.NAV_FLOAT_FIELDS, "checksum"}
    tolerance = f"checksum; attitude, velocity, position within {VM_FLOAT_STEPS} steps"
    c = Comparison(
        frame=compare_kind(
            FRAME, rec_f, rep_f, LABELS, output_every_ticks,
            lambda a, b: _frame_ok(a, b, exact), f_skip, "" if exact else tolerance,
        ),
        ext=compare_kind(
            EXT, rec_e, rep_e, LABELS, ext_every_ticks,
            lambda a, b: _ext_key(a, exact) == _ext_key(b, exact), ext_skip,
            "timing fields (tick us, overruns, GC runs)" + ("" if exact else ", float fields"),
        ),
        raw=compare_kind(
            RAW, rec_r, rep_r, LABELS, 1,
            lambda a, b: _raw_key(a) == _raw_key(b), {*RAW_TIME_FIELDS, "crc32"},
            "tick start and PPS times",
        ),
        stream_error=err or None,
        exact=exact,
    )  # fmt: skip
    c.timing_differs = sum(
        a[_TIMING] != b[_TIMING] for a, b in zip(rec_e, rep_e, strict=False) if len(a) == len(b)
    )
    return c
