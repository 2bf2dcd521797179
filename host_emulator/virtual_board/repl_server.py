"""The virtual board's Python: runs inside one persistent MicroPython VM per board session and
executes the code the host's REPL emulation (host_emulator/virtual_board/) sends it.

    micropython repl_server.py FS_DIR FLASH_KB CORRUPT_WRITES NONCE [FROZEN_DIR]

The board's filesystem: FS_DIR (a host directory) mounted at /flash through `FlashVfs`, a
Python VFS (os.mount), cwd /flash, sys.path ['', '/flash', '/flash/lib'] as on the stm32
port (with FROZEN_DIR, the modules of an image with the firmware frozen, where the port has
'.frozen': ['', FROZEN_DIR, '/flash', '/flash/lib']). It reports FLASH_KB as its capacity
(os.statvfs: 512-byte blocks, every file rounded up to whole blocks), raises OSError(28)
(ENOSPC) for a write that would exceed it, and flips one byte of each of the first
CORRUPT_WRITES writes of 16 bytes or more (a corrupted transfer).

Protocol on stdin: b"<mode> <n>\\n" then n bytes of source (mode "x": a file, as the raw
REPL compiles it; "s": one interactive line, as the friendly REPL, echoing expressions). The
code runs in one globals dict kept across requests; what it prints goes to stdout as it
runs; then the server writes SENTINEL + b"<len> <corrupted>\\n" + the exception text (len
bytes, empty if none), SENTINEL = b"\\x00\\x1bVB" + NONCE + b":".

The board's hardware, for the maintenance start (firmware/board.py, tools/flash/
maintenance.py), with the environment variables INS_VB_BACKUP (the backup domain's file) and
INS_VB_MPY (host_emulator/emulated_board/mpy): `stm` is backup_domain.py's stand-in (mem32 over the
RTC backup registers, PWR_CR and RCC_APB1ENR, nothing else), `machine` the unix port's plus
reset() and reset_cause() as the stm32 port has them. machine.reset() ends the code there: the
server writes SENTINEL + b"reset\\n" and exits (the host resets the board: a new VM, main.py
as at power-up). INS_VB_RESET_CAUSE: what reset_cause() gives (the host's reset).
"""

import io
import os
import sys

FS_DIR = sys.argv[1].rstrip("/")
CAPACITY = int(sys.argv[2]) * 1024
CORRUPT = [int(sys.argv[3]), 0]  # writes still to corrupt, writes corrupted
SENTINEL = "\x00\x1bVB" + sys.argv[4] + ":"
FROZEN = sys.argv[5:6]
BLOCK = 512
ENOSPC = 28
MIN_CORRUPT_LEN = 16


def _blocks(n):
    return (n + BLOCK - 1) // BLOCK


def _used_blocks(path):
    """Blocks the files under the host directory `path` take (each rounded up)."""
    n = 0
    for entry in os.ilistdir(path):
        name, kind = entry[0], entry[1]
        full = path + "/" + name
        if kind == 0x4000:
            n += _used_blocks(full)
        else:
            n += _blocks(os.stat(full)[6])
    return n


class FlashFile:
    """A file opened for writing on /flash: capacity check and corrupted transfers."""

    def __init__(self, f, host_path):
        self._f = f
        self._path = host_path

    def write(self, data):
        n = len(data)
        try:
            size = os.stat(self._path)[6]
        except OSError:
            size = 0
        pos = self._f.tell()
        grow = _blocks(max(size, pos + n)) - _blocks(size)
        if grow > 0 and (_used_blocks(FS_DIR) + grow) * BLOCK > CAPACITY:
            raise OSError(ENOSPC)
        if n >= MIN_CORRUPT_LEN and CORRUPT[0] > 0:
            CORRUPT[0] -= 1
            CORRUPT[1] += 1
            if isinstance(data, str):
                data = data.encode()
            data = bytearray(data)
            data[n // 2] ^= 0x5A
        return self._f.write(data)

    def read(self, *args):
        return self._f.read(*args)

    def readinto(self, *args):
        return self._f.readinto(*args)

    def readline(self, *args):
        return self._f.readline(*args)

    def seek(self, *args):
        return self._f.seek(*args)

    def tell(self):
        return self._f.tell()

    def flush(self):
        return self._f.flush()

    def close(self):
        return self._f.close()

    def __enter__(self):
        return self

    def __exit__(self, *args):
        self._f.close()

    def __iter__(self):
        return iter(self._f)


class FlashVfs:
    """/flash: the host directory FS_DIR (paths as the VFS layer gives them: absolute within
    the mount, or relative to this filesystem's cwd)."""

    def __init__(self, root):
        self.root = root
        self.cwd = "/"

    def _host(self, path):
        if not path.startswith("/"):
            path = self.cwd.rstrip("/") + "/" + path
        parts = []
        for p in path.split("/"):
            if p == "..":
                if parts:
                    parts.pop()
            elif p and p != ".":
                parts.append(p)
        return self.root + "/" + "/".join(parts) if parts else self.root

    def mount(self, readonly, mkfs):
        pass

    def umount(self):
        pass

    def ilistdir(self, path):
        """(name, type, inode, size) as the stm32 port's FAT gives them (the unix port's
        entries have no size, which `mpremote fs ls` would show as 0)."""
        host = self._host(path)
        for entry in os.ilistdir(host):
            size = 0 if entry[1] == 0x4000 else os.stat(host + "/" + entry[0])[6]
            yield (entry[0], entry[1], 0, size)

    def stat(self, path):
        return os.stat(self._host(path))

    def statvfs(self, path):
        total = CAPACITY // BLOCK
        free = max(0, total - _used_blocks(self.root))
        return (BLOCK, BLOCK, total, free, free, 0, 0, 0, 0, 255)

    def open(self, path, mode):
        host = self._host(path)
        f = open(host, mode)
        if "w" in mode or "a" in mode or "+" in mode or "x" in mode:
            return FlashFile(f, host)
        return f

    def chdir(self, path):
        host = self._host(path)
        if os.stat(host)[0] & 0x4000 == 0:
            raise OSError(20)  # ENOTDIR
        self.cwd = "/" + host[len(self.root) :].strip("/")

    def getcwd(self):
        return self.cwd if self.cwd == "/" else self.cwd.rstrip("/")

    def mkdir(self, path):
        os.mkdir(self._host(path))

    def rmdir(self, path):
        os.rmdir(self._host(path))

    def remove(self, path):
        os.remove(self._host(path))

    def rename(self, old, new):
        os.rename(self._host(old), self._host(new))


class _Reset(BaseException):
    """machine.reset(): the code ends here, the board resets."""


class _Machine:
    """The REPL's `machine`: the unix port's, plus the stm32 port's reset() and reset_cause()
    (its constants: ports/stm32/modmachine.c)."""

    SOFT_RESET = 0
    PWRON_RESET = 1
    HARD_RESET = 2
    WDT_RESET = 3
    DEEPSLEEP_RESET = 4

    def __init__(self, unix):
        for name in dir(unix):
            if not name.startswith("__"):
                setattr(self, name, getattr(unix, name))

    def reset(self):
        raise _Reset()

    def reset_cause(self):
        return int(os.getenv("INS_VB_RESET_CAUSE") or 1)


def _hardware():
    """`stm` and `machine` as the board has them (module docstring), when the host gives the
    backup domain's file."""
    path = os.getenv("INS_VB_BACKUP")
    if not path:
        return
    import machine

    sys.path.insert(0, os.getenv("INS_VB_MPY"))
    import backup_domain

    sys.path.pop(0)
    sys.modules["stm"] = backup_domain.Stm(path)
    sys.modules["machine"] = _Machine(machine)


def _report(err):
    b = err.encode()
    sys.stdout.write(SENTINEL + str(len(b)) + " " + str(CORRUPT[1]) + "\n")
    sys.stdout.write(err)


def _run(src, mode, g):
    try:
        code = compile(src, "<stdin>", "single" if mode == "s" else "exec")
        exec(code, g)
    except _Reset:
        raise
    except BaseException as e:  # noqa: BLE001  (reported like the board's REPL)
        s = io.StringIO()
        sys.print_exception(e, s)
        lines = s.getvalue().split("\n")
        # drop this server's own frame: the board's traceback starts at <stdin>
        return "\n".join(x for x in lines if "repl_server.py" not in x)
    return ""


def main():
    _hardware()
    os.mount(FlashVfs(FS_DIR), "/flash")
    os.chdir("/flash")
    sys.path.clear()
    sys.path.extend([""] + FROZEN + ["/flash", "/flash/lib"])
    g = {"__name__": "__main__"}
    stdin = sys.stdin.buffer
    while True:
        try:
            header = stdin.readline()
            if not header:
                return
            mode, n = header.split()
            n = int(n)
            src = stdin.read(n) if n else b""
            while len(src) < n:
                more = stdin.read(n - len(src))
                if not more:
                    return
                src += more
        except KeyboardInterrupt:  # a Ctrl-C that came after the code finished
            continue
        try:
            err = _run(src.decode(), mode.decode(), g)
        except _Reset:
            sys.stdout.write(SENTINEL + "reset\n")
            return
        try:
            _report(err)
        except KeyboardInterrupt:
            _report(err)


main()
