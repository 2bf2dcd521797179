"""Two output streams of one input compared record by record: parity (the firmware against the
NumPy model) and session replay (a board's recording against its replay) both use this.

Each kind of record (52-byte frames, extended frames, raw-input records; proto/stream.split) is
compared in order: the first record that differs is named with its tick and its differing
fields (decoded by proto/frame.py and proto/records.py; floats shown with their float32 bits),
or the first record one side lacks.
"""

import struct
from dataclasses import dataclass, field

from common.proto import frame, records

FRAME, EXT, RAW = "frame", "extended frame", "raw record"


@dataclass
class FieldDiff:
    name: str
    values: tuple  # (side a's, side b's)
    labels: tuple  # the sides' names

    def __str__(self):
        (la, lb), (a, b) = self.labels, self.values
        return f"{self.name} {la} {a} {lb} {b}"


@dataclass
class KindResult:
    """One kind of record: how many each side has, how many were compared, the first
    difference and what was left out of the comparison."""

    kind: str  # FRAME, EXT or RAW
    labels: tuple  # the two sides' names, e.g. ("firmware", "model")
    counts: tuple  # records on each side
    compared: int = 0  # records present on both sides
    first: int | None = None  # index of the first differing (or missing) record
    tick: int | None = None  # its tick
    fields: list = field(default_factory=list)  # FieldDiff of that record
    excluded: str = ""  # what is not compared, in words

    def count(self, label):
        return self.counts[self.labels.index(label)]

    @property
    def identical(self):
        return self.first is None and self.counts[0] == self.counts[1]

    def line(self, tick_us, same="identical"):
        """One summary line, e.g. "frames: 10000 compared, identical"."""
        line = f"{self.kind}s: {self.compared} compared"
        if self.counts[0] != self.counts[1]:
            (la, lb), (a, b) = self.labels, self.counts
            line += f" ({la} {a}, {lb} {b})"
        if self.first is None:
            line += f", {same}" if self.counts[0] == self.counts[1] else ""
        else:
            where = f"{self.kind} {self.first}"
            if self.tick is not None:
                where += f" (tick {self.tick}, t = {self.tick * tick_us * 1e-6:.3f} s)"
            line += f", first difference at {where}: " + "; ".join(map(str, self.fields))
        return line


def _show(v):
    if isinstance(v, float):
        return f"{v!r} (0x{struct.unpack('<I', struct.pack('<f', v))[0]:08x})"
    return v


def _flat(d):
    """A decoder's field dict with lists expanded to name[i]; floats shown with their bits."""
    items = []
    for name, v in d.items():
        if isinstance(v, (bytes, bytearray)):
            items.append((name, v.hex()))
        elif isinstance(v, list):
            items.extend((f"{name}[{i}]", _show(x)) for i, x in enumerate(v))
        else:
            items.append((name, _show(v)))
    return items


def record_fields(kind, rec):
    """[(name, value)] of one record: a frame's integer fields as the bytes hold them (proto/
    frame.py's names), a record's decoded fields and its CRC."""
    if kind == FRAME:
        return list(zip(frame.NAMES, frame.STRUCT.unpack(rec), strict=True))
    try:
        d = records.decode_ext(rec) if kind == EXT else records.decode_raw(rec)
    except struct.error:  # a length the decoder does not know
        return [("bytes", rec.hex())]
    return _flat(d) + [("crc32", rec[-4:].hex())]


def field_diffs(kind, a, b, labels, skip=()):
    """The FieldDiffs of two records of one kind (fields in `skip`, or whose name before [i]
    is, left out); the whole records when only left-out fields differ."""
    fa = record_fields(kind, a)
    fb = record_fields(kind, b)
    if [n for n, _ in fa] != [n for n, _ in fb]:
        return [FieldDiff("length", (len(a), len(b)), labels)]
    out = [
        FieldDiff(n, (x, y), labels)
        for (n, x), (_, y) in zip(fa, fb, strict=True)
        if x != y and n not in skip and n.split("[")[0] not in skip
    ]
    return out or [FieldDiff("bytes", (a.hex(), b.hex()), labels)]


def compare_kind(kind, recs_a, recs_b, labels, every, same=None, skip=(), excluded=""):
    """KindResult of two lists of records of one kind. every: ticks per record (its tick is
    (index + 1) * every - 1), 0 if unknown; same(a, b): whether two records count as equal
    (default: equal bytes); skip: field names the difference report leaves out."""
    same = same or (lambda a, b: a == b)
    r = KindResult(kind, labels, (len(recs_a), len(recs_b)), min(len(recs_a), len(recs_b)))
    r.excluded = excluded
    for i in range(r.compared):
        if not same(recs_a[i], recs_b[i]):
            r.first = i
            r.fields = field_diffs(kind, recs_a[i], recs_b[i], labels, skip)
            break
    else:
        if len(recs_a) != len(recs_b):
            r.first = r.compared
            present = (r.compared < len(recs_a), r.compared < len(recs_b))
            r.fields = [FieldDiff("present", present, labels)]
    if r.first is not None and every:
        r.tick = (r.first + 1) * every - 1
    return r
