"""The UsartGPU serial display as seen from the board's display UART: a strict parser of the
byte stream the firmware sends it, and the drawing state that stream builds.

What the screen is documented to understand (the public "Usart GPU" manual of 2014 and the
drivers that use it; only what is publicly confirmed is accepted here):

- ASCII commands, each ending in `;`, several to a batch; a batch runs when `\\r\\n` arrives,
  and the screen answers `OK\\r\\n` once it has drawn it;
- `CLS(c);` clear to colour c; `SBC(c);` the background colour of text;
  `DS12(x,y,'text',c);`, `DS16`, `DS24`, `DS32`: text by font height in pixels;
  `BOX(x1,y1,x2,y2,c);` a rectangle's outline, `BOXF(...)` a filled one;
  `PL(x1,y1,x2,y2,c);` a line; `PS(x,y,c);` a pixel;
- colours are palette indices 0..255 (0 black; what the others look like is a setting of the
  renderer, not something the stream says).

Strict on purpose: the real screen ignores what it does not understand, so a firmware bug
(a command cut by a full buffer, an unknown name, a coordinate off the screen, text it cannot
show) would go unseen on a board. Here each is a `DisplayError` that names the batch's bytes
and the offset.
"""

from dataclasses import dataclass

from common.errors import EmulatorError

END = b"\r\n"  # ends a batch: the screen draws what came before it
REPLY = b"OK\r\n"
# command name -> argument kinds: "i" a non-negative integer, "s" a quoted ASCII text
SIGNATURES = {
    "CLS": "i",
    "SBC": "i",
    "DS12": "iisi",
    "DS16": "iisi",
    "DS24": "iisi",
    "DS32": "iisi",
    "BOX": "iiiii",
    "BOXF": "iiiii",
    "PL": "iiiii",
    "PS": "iii",
}
# the x and y coordinates among each command's arguments (by position, x first)
_XY = {
    "DS12": (0, 1),
    "DS16": (0, 1),
    "DS24": (0, 1),
    "DS32": (0, 1),
    "BOX": (0, 1, 2, 3),
    "BOXF": (0, 1, 2, 3),
    "PL": (0, 1, 2, 3),
    "PS": (0, 1),
}
_MAX_BATCH = 4096  # bytes without a "\r\n": a stream that never ends a batch


class DisplayError(EmulatorError):
    """A byte stream the screen would not draw as the firmware meant it."""


@dataclass(frozen=True)
class Command:
    name: str  # "CLS", "DS16", ...
    args: tuple  # ints, and for DSnn one str
    offset: int  # where it starts in the stream, bytes

    @property
    def colour(self):
        return self.args[-1]


def _context(data, at, width=24):
    """The bytes around `at`, for an error message."""
    lo = max(0, at - width)
    return f"{bytes(data[lo:at])!r} >>> {bytes(data[at : at + width])!r}"


def parse_batch(batch, size, base=0):
    """The commands of one batch (its bytes without the ending "\\r\\n"), each checked
    against its signature and the screen's (width, height); `base` is the batch's offset in
    the stream, for the messages. Raises DisplayError naming the bytes."""
    cmds = []
    i = 0
    n = len(batch)
    while i < n:
        start = i
        while i < n and (65 <= batch[i] <= 90 or 48 <= batch[i] <= 57):  # A-Z, 0-9
            i += 1
        name = batch[start:i].decode("ascii")
        if not name:
            raise DisplayError(f"byte {base + i}: a command name expected: {_context(batch, i)}")
        if name not in SIGNATURES:
            raise DisplayError(
                f"byte {base + start}: unknown command {name!r} (known: "
                f"{', '.join(SIGNATURES)}): {_context(batch, start)}"
            )
        if i >= n or batch[i] != ord("("):
            raise DisplayError(f"byte {base + i}: '(' expected after {name}: {_context(batch, i)}")
        i += 1
        args = []
        kinds = SIGNATURES[name]
        for k, kind in enumerate(kinds):
            if kind == "s":
                if i >= n or batch[i] != ord("'"):
                    raise DisplayError(
                        f"byte {base + i}: {name}'s text must be quoted: {_context(batch, i)}"
                    )
                j = batch.find(b"'", i + 1)
                if j < 0:
                    raise DisplayError(
                        f"byte {base + i}: {name}'s text is not closed: {_context(batch, i)}"
                    )
                text = batch[i + 1 : j]
                bad = [b for b in text if not 32 <= b <= 126]
                if bad:
                    raise DisplayError(
                        f"byte {base + i}: {name}'s text holds a byte the renderer has no "
                        f"glyph for (0x{bad[0]:02X}; ASCII only): {_context(batch, i)}"
                    )
                args.append(text.decode("ascii"))
                i = j + 1
            else:
                j = i
                while j < n and 48 <= batch[j] <= 57:
                    j += 1
                if j == i or j - i > 5:
                    raise DisplayError(
                        f"byte {base + i}: {name}'s argument {k + 1} must be a number of 1-5 "
                        f"digits: {_context(batch, i)}"
                    )
                args.append(int(batch[i:j]))
                i = j
            sep = ord(",") if k < len(kinds) - 1 else ord(")")
            if i >= n or batch[i] != sep:
                raise DisplayError(
                    f"byte {base + i}: {chr(sep)!r} expected in {name} after argument {k + 1} "
                    f"({len(kinds)} arguments): {_context(batch, i)}"
                )
            i += 1
        if i >= n or batch[i] != ord(";"):
            raise DisplayError(f"byte {base + i}: ';' expected after {name}(...): "
                               f"{_context(batch, i)}")  # fmt: skip
        i += 1
        cmd = Command(name, tuple(args), base + start)
        _check(cmd, size, batch, start, base)
        cmds.append(cmd)
    return cmds


def _check(cmd, size, batch, start, base):
    """Coordinates on the screen, the colour a palette index, a box's corners in order."""
    w, h = size
    a = cmd.args
    if cmd.colour > 255:
        raise DisplayError(f"byte {base + start}: {cmd.name}'s colour {cmd.colour} is beyond the "
                           f"palette (0..255): {_context(batch, start)}")  # fmt: skip
    for k in _XY.get(cmd.name, ()):
        limit = w if k % 2 == 0 else h
        if a[k] >= limit:
            axis = "x" if k % 2 == 0 else "y"
            raise DisplayError(
                f"byte {base + start}: {cmd.name}'s {axis} {a[k]} is off the {w}x{h} screen: "
                f"{_context(batch, start)}"
            )
    if cmd.name.startswith("DS"):
        fh = int(cmd.name[2:])
        if a[0] + fh // 2 * len(a[2]) > w or a[1] + fh > h:
            raise DisplayError(
                f"byte {base + start}: {cmd.name}'s text ({len(a[2])} cells of {fh // 2}x{fh} "
                f"from {a[0]},{a[1]}) runs off the {w}x{h} screen: {_context(batch, start)}"
            )
    if cmd.name in ("BOX", "BOXF") and (a[2] < a[0] or a[3] < a[1]):
        raise DisplayError(f"byte {base + start}: {cmd.name}'s second corner is above or left "
                           f"of its first: {_context(batch, start)}")  # fmt: skip


class Stream:
    """The display UART's receiver: bytes in (`feed`), whole batches out as commands. What
    follows the last "\\r\\n" waits for the next one (a batch may span many writes)."""

    def __init__(self, size):
        self.size = size
        self._pending = bytearray()
        self._base = 0  # stream offset of self._pending[0]
        self.batches = 0

    def feed(self, data):
        """The commands of every batch `data` completes, in order."""
        self._pending += data
        out = []
        while True:
            end = self._pending.find(END)
            if end < 0:
                break
            out += parse_batch(bytes(self._pending[:end]), self.size, self._base)
            del self._pending[: end + len(END)]
            self._base += end + len(END)
            self.batches += 1
        if len(self._pending) > _MAX_BATCH:
            raise DisplayError(
                f"byte {self._base}: {len(self._pending)} bytes without a \\r\\n: the screen "
                f"never draws them: {_context(self._pending, 0)}"
            )
        return out

    @property
    def pending(self):
        """Bytes received after the last complete batch (not drawn yet)."""
        return bytes(self._pending)
