"""`python -m tools.flash deploy` and `config` end to end against the virtual board (a real
MicroPython VM behind a pty, host_emulator.virtual_board), plus the port errors a user meets:
no such port, a device that is not MicroPython, a silent one. Every write (and every read that
restarts the firmware) goes through the maintenance start: the virtual board's REPL has the
stm32 port's `stm.mem32` over the RTC backup registers and machine.reset(), and its firmware
starts with main.py's maintenance check (test_maintenance.py: the protocol's edge cases)."""

import json
import os
import pathlib
import shutil
import subprocess
import threading

import pytest

from tools.flash import build, deploy
from tools.flash.__main__ import main

virtual_board = pytest.importorskip("host_emulator.virtual_board")


def _quiet(_line):
    pass


@pytest.fixture(scope="module")
def build_dir(flash_build_dir):
    """The session's build (tests/conftest.py)."""
    return flash_build_dir


def _board(tmp_path, **kw):
    kw.setdefault("realtime", False)
    kw.setdefault("duration_s", 30.0)
    return virtual_board.VirtualBoard(tmp_path / "flash", **kw)


def _crcs(root):
    return {
        p.relative_to(root).as_posix(): build.crc32(p.read_bytes())
        for p in root.rglob("*")
        if p.is_file()
    }


def _expected_crcs(manifest):
    """What the virtual board should hold: the build, with the native kernels built for its
    VM (x64: deploy asks the board its architecture) instead of the board's armv7emsp."""
    want = {f["path"]: int(f["crc32"], 16) for f in manifest["files"]}
    want[build.NATIVE_PATH] = build.crc32(build.native_module("x64").read_bytes())
    return want


def test_deploy_copies_what_differs_only_and_deletes_stale_firmware(build_dir, tmp_path):
    with _board(tmp_path) as vb:
        first = deploy.deploy(build_dir, vb.port, log=_quiet)
        manifest = build.load_manifest(build_dir)
        assert sorted(first["written"]) == sorted(f["path"] for f in manifest["files"])
        assert _crcs(vb.fs_dir) == _expected_crcs(manifest)
        assert "kernels: native" in first["console"]  # the x64 navk.mpy loads in the VM
        assert "ins: running" in first["console"]

        second = deploy.deploy(build_dir, vb.port, log=_quiet)
        assert second["written"] == [] and second["stale"] == []

        nav = vb.fs_dir / "lib" / "geo.mpy"
        nav.write_bytes(nav.read_bytes()[:-1] + b"\x00")  # one file differs
        (vb.fs_dir / "lib" / "old_module.py").write_text("x = 1\n")  # stale firmware
        (vb.fs_dir / "lib" / "nav.py").write_text("shadowing = True\n")  # would shadow nav.mpy
        (vb.fs_dir / "track.log").write_text("user data\n")  # never touched
        third = deploy.deploy(build_dir, vb.port, log=_quiet)
        assert third["written"] == ["lib/geo.mpy"]
        assert third["stale"] == ["lib/nav.py", "lib/old_module.py"]
        assert not (vb.fs_dir / "lib" / "old_module.py").exists()
        assert (vb.fs_dir / "track.log").read_text() == "user data\n"
        assert _crcs(vb.fs_dir)["lib/geo.mpy"] == build.crc32(
            (build_dir / "lib/geo.mpy").read_bytes()
        )


def test_deploy_and_config_set_write_in_a_maintenance_start(build_dir, tmp_path, capsys):
    """The board reset into maintenance (its main.py's check took the marker: neither loop
    nor watchdog) before anything is written, then soft-reset into a normal start that clears
    the marker. The first deploy finds no main.py: reset, but no maintenance start to take."""
    with _board(tmp_path) as vb:
        lines = []
        deploy.deploy(build_dir, vb.port, log=lines.append)
        assert (vb.resets, vb.maintenance_starts) == (1, 0)
        assert "the board restarted without starting a firmware (no main.py): no watchdog runs" \
            in lines  # fmt: skip
        lines = []
        second = deploy.deploy(build_dir, vb.port, log=lines.append)
        assert (vb.resets, vb.maintenance_starts) == (2, 1)
        assert lines[:2] == [
            f"resetting the board on {vb.port} into maintenance (the firmware's loop and "
            "watchdog off while its filesystem is written)",
            "the board restarted in maintenance: loop and watchdog off",
        ]
        assert "ins: running" in second["console"]
        marker = vb._backup.read_bytes()[4 * 18 : 4 * 19]  # RTC_BKP18R
        assert marker == bytes(4)  # the normal start cleared it
        capsys.readouterr()
        # config set: a read (config get's session) and the write, each in maintenance; the
        # read's soft reset may still be starting the firmware when the write's Ctrl-C comes,
        # before main.py cleared the marker: that start is still a maintenance one (nothing
        # runs, no watchdog), and the write goes on without another reset
        assert main(["config", "set", "--port", vb.port, "output_every_ticks=2"]) == 0
        out, err = capsys.readouterr()
        assert "the board restarted in maintenance" in err  # the read's log goes to stderr
        if vb.resets == 3:
            assert "the board is in maintenance (loop and watchdog off) from an earlier " \
                   "start" in out  # fmt: skip
        else:
            assert vb.resets == 4 and "the board restarted in maintenance" in out
        assert vb.maintenance_starts == vb.resets - 1


def test_the_virtual_boards_stm_refuses_what_it_does_not_have(tmp_path):
    """The REPL's `stm.mem32` stand-in knows the RTC backup registers, PWR_CR and
    RCC_APB1ENR: any other address is refused, never read as 0; a backup register written
    without PWR_CR.DBP keeps its value, as on the chip."""
    with _board(tmp_path) as vb:
        ser, repl = deploy.connect(vb.port, 115200, maintenance=False)
        try:
            out = repl.exec(
                "import stm\nm = stm.mem32\nm[0x40002898] = 7\nprint(m[0x40002898])\n"
                "m[0x40007000] = m[0x40007000] | 0x100\nm[0x40002898] = 7\n"
                "print(m[0x40002898], stm.RTC + stm.RTC_BKP18R == 0x40002898)\n"
                "try:\n m[0x40011004]\nexcept ValueError as e:\n print('refused', e)\n"
            ).decode()
        finally:
            ser.close()
    assert out.splitlines()[:2] == ["0", "7 True"]
    assert "refused the virtual board's stm.mem32 has no register at 40011004" in out


def test_a_corrupted_write_is_retried(build_dir, tmp_path):
    lines = []
    with _board(tmp_path, corrupt_writes=1) as vb:
        result = deploy.deploy(build_dir, vb.port, log=lines.append)
    assert any("attempt 1" in line for line in lines)
    assert any("OK after 2 attempts" in line for line in lines)
    manifest = build.load_manifest(build_dir)
    assert _crcs(tmp_path / "flash") == _expected_crcs(manifest)
    assert "ins: running" in result["console"]


def test_persistent_corruption_fails_naming_the_file_and_what_to_do(tmp_path, capsys):
    with _board(tmp_path, corrupt_writes=100) as vb:
        assert main(["deploy", "--port", vb.port]) == 1
    err = capsys.readouterr().err
    assert "was corrupted" in err and "after 3 attempts" in err
    assert "USB cable" in err and "lower --baud" in err and "only the files that differ" in err
    assert "Traceback" not in err


def test_flash_full_before_writing_anything(build_dir, tmp_path, capsys):
    with _board(tmp_path, flash_kb=48) as vb:
        assert main(["deploy", "--port", vb.port]) == 1
        assert [p for p in vb.fs_dir.rglob("*")] == []
    err = capsys.readouterr().err
    assert "flash full" in err and "49152 bytes" in err and "Nothing was written" in err
    assert "SPI flash" in err


def test_config_upload_get_and_set_round_trip(tmp_path, capsys):
    cfg = tmp_path / "ins.cfg"
    assert (
        main(["config", "set", "--file", str(cfg), "gnss_baud=38400", "lever_b_m=0.1,0,-0.2"]) == 0
    )
    assert main(["config", "get", "--file", str(cfg)]) == 0
    assert "gnss_baud = 38400" in capsys.readouterr().out
    with _board(tmp_path) as vb:
        assert main(["deploy", "--port", vb.port, "--config", str(cfg)]) == 0
        out = capsys.readouterr().out
        assert "configuration /flash/ins.cfg loaded" in out and "ins: running" in out
        assert (vb.fs_dir / "ins.cfg").read_bytes() == cfg.read_bytes()

        assert main(["config", "get", "--port", vb.port]) == 0
        out = capsys.readouterr().out
        assert "gnss_baud = 38400" in out and "lever_b_m = 0.100000001,0,-0.200000003" in out

        assert main(["config", "set", "--port", vb.port, "output_every_ticks=2"]) == 0
        assert "soft reset" in capsys.readouterr().out
        saved = tmp_path / "back.cfg"
        assert main(["config", "get", "--port", vb.port, "--out", str(saved)]) == 0
        out, err = capsys.readouterr()
        assert "output_every_ticks = 2" in out and "gnss_baud = 38400" in out
        assert saved.read_bytes() == (vb.fs_dir / "ins.cfg").read_bytes()
        assert (
            err.startswith("note: to read /flash/ins.cfg, the firmware on ") and "restarted" in err
        )

        # deploy --set changes the board's configuration (no --config): raw_record for sessions
        assert main(["deploy", "--port", vb.port, "--set", "raw_record=1"]) == 0
        deployed = capsys.readouterr().out
        assert main(["config", "get", "--file", str(vb.fs_dir / "ins.cfg")]) == 0
        out = capsys.readouterr().out
        assert "raw_record = 1" in out and "output_every_ticks = 2" in out, deployed
        assert "gnss_baud = 38400" in out


@pytest.mark.parametrize(
    "setting, message",
    [
        ("gnss_baud=1234", "gnss_baud must be one of"),
        ("no_such=1", "unknown setting 'no_such'"),
        ("lever_b_m=1,2", "takes 3 comma-separated numbers"),
        ("profile=car", "profile must be an integer"),
    ],
)
def test_config_set_rejects_bad_settings(tmp_path, capsys, setting, message):
    assert main(["config", "set", "--file", str(tmp_path / "c.cfg"), setting]) == 1
    assert message in capsys.readouterr().err
    assert not (tmp_path / "c.cfg").exists()


def test_deploy_rejects_an_invalid_config_file_before_connecting(tmp_path, capsys):
    bad = tmp_path / "bad.cfg"
    bad.write_bytes(b"INSC not really")
    assert main(["deploy", "--port", "/dev/nonexistent-port", "--config", str(bad)]) == 1
    assert "not a valid configuration file" in capsys.readouterr().err


def test_deploy_confirms_frames_on_the_rs485_port(build_dir, tmp_path):
    with _board(tmp_path) as vb:
        result = deploy.deploy(build_dir, vb.port, frames_port=vb.rs485_port, log=_quiet)
    assert "ins: running" in result["console"]
    assert result["frames"] >= 3


def test_firmware_that_fails_to_start_is_reported_with_its_console(build_dir, tmp_path):
    broken = tmp_path / "broken"
    shutil.copytree(build_dir, broken)
    src = tmp_path / "app.py"
    src.write_text("raise RuntimeError('IMU wiring')\n")
    app = broken / "app.mpy"
    subprocess.run([str(build.MPY_CROSS), "-s", "app.py", "-o", str(app), str(src)], check=True)
    manifest = build.load_manifest(broken)
    for f in manifest["files"]:
        if f["path"] == "app.mpy":
            data = app.read_bytes()
            f["size"], f["crc32"] = len(data), f"{build.crc32(data):08x}"
    (broken / "manifest.json").write_text(json.dumps(manifest))
    with _board(tmp_path) as vb:
        with pytest.raises(deploy.FirmwareNotRunning, match="IMU wiring") as e:
            deploy.deploy(broken, vb.port, log=_quiet, watch_s=10)
    assert "written and verified" in str(e.value)


def test_no_such_port_lists_the_ports(capsys):
    assert main(["deploy", "--port", "/dev/ttyNOPE9"]) == 1
    err = capsys.readouterr().err
    assert "no serial port /dev/ttyNOPE9" in err and "Ports on this machine" in err
    assert "Traceback" not in err


def _pty(answer):
    """A pty whose far end answers every write with answer (None: never answers)."""
    master, slave = os.openpty()
    name = os.ttyname(slave)
    stop = threading.Event()

    def serve():
        while not stop.is_set():
            try:
                data = os.read(master, 1024)
            except OSError:
                return
            if data and answer is not None:
                os.write(master, answer)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    return name, (master, slave, stop)


def _close_pty(handle):
    master, slave, stop = handle
    stop.set()
    os.close(slave)
    os.close(master)


def test_a_device_answering_garbage_is_not_micropython(capsys):
    name, handle = _pty(b"\x00\x17GNGGA,garbage\xff\r\n")
    try:
        assert main(["deploy", "--port", name]) == 1
    finally:
        _close_pty(handle)
    err = capsys.readouterr().err
    assert "not in MicroPython" in err and "GNGGA" in err


def test_a_silent_device_is_not_responding(capsys):
    name, handle = _pty(None)
    try:
        assert main(["config", "get", "--port", name]) == 1
    finally:
        _close_pty(handle)
    err = capsys.readouterr().err
    assert "does not respond" in err and "Traceback" not in err


def test_dry_run_writes_nothing(build_dir, tmp_path):
    with _board(tmp_path) as vb:
        result = deploy.deploy(build_dir, vb.port, dry_run=True, log=_quiet)
        built = json.loads((build_dir / "manifest.json").read_text())["files"]
        assert result["dry_run"] and len(result["planned"]) == len(built)
        assert build.NATIVE_PATH in {f["path"] for f in result["planned"]}
        assert list(pathlib.Path(vb.fs_dir).rglob("*")) == []
        assert not result["restarted"]  # no firmware was running


def test_dry_run_leaves_a_running_firmware_running(build_dir, tmp_path):
    """--dry-run stops the firmware to read the board (Ctrl-C): it restarts it after, and
    says so; nothing on /flash changes."""
    with _board(tmp_path) as vb:
        deploy.deploy(build_dir, vb.port, log=_quiet)
        before = _crcs(vb.fs_dir)
        lines = []
        result = deploy.deploy(build_dir, vb.port, dry_run=True, log=lines.append)
        assert result["restarted"] and "runs again" in lines[-1]
        assert _crcs(vb.fs_dir) == before
        again = deploy.deploy(build_dir, vb.port, dry_run=True, log=_quiet)
        assert again["restarted"]  # the first dry run left it running


def test_a_port_held_by_another_program_is_busy(capsys):
    import serial

    name, handle = _pty(None)
    holder = serial.Serial(name, exclusive=True)
    try:
        assert main(["config", "get", "--port", name]) == 1
    finally:
        holder.close()
        _close_pty(handle)
    err = capsys.readouterr().err
    assert "is busy" in err and "another program" in err


def test_the_console_shows_the_firmware_and_takes_ctrl_c_and_ctrl_d(build_dir, tmp_path):
    """`python -m tools.flash console` (mpremote repl) on the virtual board, from a terminal
    (a pty: mpremote's console wants one): Ctrl-C stops the firmware, which says so; Ctrl-D
    restarts it; Ctrl-] leaves, exit status 0."""
    from console_pty import Console

    with _board(tmp_path, realtime=True, duration_s=120.0) as vb:
        deploy.deploy(build_dir, vb.port, log=_quiet)
        with Console(vb.port) as c:
            assert c.ready(), bytes(c.seen)
            c.send(b"\x03")
            assert c.read_until(b"ins: stopped"), bytes(c.seen)
            c.send(b"\x04")
            assert c.read_until(b"ins: running"), bytes(c.seen)
            assert c.leave() == 0, bytes(c.seen)
