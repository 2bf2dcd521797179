"""deploy on a board whose MicroPython image carries the firmware frozen (tools/image: the
frozen `fwid` module): only main.py and ins.cfg are written and the firmware files on /flash
go; another firmware frozen is refused before anything is written. On the scripted board
(tests/tools/fakeboard.py, pretending to have `fwid`) and end to end on the virtual board with
a frozen-firmware directory, where the firmware then runs from the frozen modules alone."""

import pytest
from fakeboard import FakeSerial

from tools.flash import build, deploy
from tools.flash.__main__ import main
from tools.image import fwid


@pytest.fixture(scope="module")
def build_dir(flash_build_dir):
    """The session's build (tests/conftest.py)."""
    return flash_build_dir


@pytest.fixture(scope="module")
def host_id():
    return fwid.host_id()


def _fwid(crc, board="WEACT_F411_BLACKPILL"):
    return {
        "fwid": {
            "FIRMWARE_CRC32": crc,
            "FIRMWARE_VERSION": "0.1.0",
            "MICROPYTHON": "1.28.0",
            "BOARD": board,
        }
    }


def _old_files_deployed(fs, build_dir):
    """A /flash as a file deploy left it, plus user data."""
    for f in build.load_manifest(build_dir)["files"]:
        dest = fs / f["path"]
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_bytes((build_dir / f["path"]).read_bytes())
    (fs / "ins.cfg").write_bytes(b"INSC old configuration")
    (fs / "track.log").write_text("user data\n")


def _fake(monkeypatch, fs, **kw):
    fake = FakeSerial(fs, **kw)
    monkeypatch.setattr(deploy, "open_port", lambda port, baud: fake)
    return fake


def test_frozen_firmware_gets_main_py_and_navk_only_and_firmware_files_go(
    build_dir, host_id, tmp_path, monkeypatch
):
    fs = tmp_path / "flash"
    _old_files_deployed(fs, build_dir)
    (fs / "main.py").write_text("# an older main.py\n")
    fake = _fake(monkeypatch, fs, frozen=_fwid(host_id["crc32"]))
    lines = []
    result = deploy.deploy(build_dir, "/dev/fake", log=lines.append, watch_s=2)
    assert result["written"] == ["main.py"]
    assert result["frozen"]["crc32"] == host_id["crc32"]
    assert fake.written == ["/flash/main.py"]
    left = sorted(p.relative_to(fs).as_posix() for p in fs.rglob("*"))
    # drivers/ would hide the package; the native kernels stay (a natmod cannot be frozen)
    assert left == ["ins.cfg", "lib", "lib/navk.mpy", "main.py", "track.log"]
    assert (fs / "main.py").read_bytes() == (build_dir / "main.py").read_bytes()
    n_files = len(build.load_manifest(build_dir)["files"])
    assert len(result["stale"]) == n_files - 2 and "lib/nav.mpy" in result["stale"]
    text = "\n".join(lines)
    assert f"carries this firmware frozen (id {host_id['crc32']}" in text
    assert "only main.py and lib/navk.mpy go to /flash" in text
    assert "the F411's 46 KB of files are no longer a limit" in text
    assert "deleted stale lib/nav.mpy (frozen in the image)" in text
    assert "removed /flash/drivers/ (it would hide the frozen drivers package)" in text

    again = deploy.deploy(build_dir, "/dev/fake", log=lines.append, watch_s=2)
    assert again["written"] == [] and again["stale"] == []


def test_frozen_firmware_with_a_configuration(build_dir, host_id, tmp_path, monkeypatch, capsys):
    cfg = tmp_path / "ins.cfg"
    assert main(["config", "set", "--file", str(cfg), "gnss_baud=38400"]) == 0
    fs = tmp_path / "flash"
    fs.mkdir()
    fake = _fake(monkeypatch, fs, frozen=_fwid(host_id["crc32"]))
    # --flash-kb 48 would refuse the files (they need 54.5 KB): with the firmware frozen it is moot
    assert main(["deploy", "--port", "/dev/fake", "--config", str(cfg), "--flash-kb", "48",
                 "--watch", "2"]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert "only main.py, lib/navk.mpy and ins.cfg go to /flash" in out and "deploy OK" in out
    assert fake.written == ["/flash/lib/navk.mpy", "/flash/main.py", "/flash/ins.cfg"]
    assert (fs / "ins.cfg").read_bytes() == cfg.read_bytes()


def test_another_frozen_firmware_is_refused_before_writing(build_dir, tmp_path, monkeypatch):
    fs = tmp_path / "flash"
    _old_files_deployed(fs, build_dir)
    before = {p: p.read_bytes() for p in fs.rglob("*") if p.is_file()}
    fake = _fake(monkeypatch, fs, frozen=_fwid("0badf00d", "NUCLEO_F411RE"))
    with pytest.raises(deploy.FrozenMismatch) as e:
        deploy.deploy(build_dir, "/dev/fake", log=lambda _: None, watch_s=2)
    msg = str(e.value)
    assert "another firmware frozen (id 0badf00d, version 0.1.0, built for NUCLEO_F411RE)" in msg
    assert "make image BOARD=NUCLEO_F411RE" in msg and "make flash-image BOARD=NUCLEO_F411RE" in msg
    assert "Nothing was written" in msg
    assert fake.written == []
    assert {p: p.read_bytes() for p in fs.rglob("*") if p.is_file()} == before


def test_user_files_in_drivers_would_hide_the_frozen_package(
    build_dir, host_id, tmp_path, monkeypatch
):
    fs = tmp_path / "flash"
    (fs / "drivers").mkdir(parents=True)
    (fs / "drivers" / "notes.txt").write_text("mine\n")
    _fake(monkeypatch, fs, frozen=_fwid(host_id["crc32"]))
    with pytest.raises(deploy.FlashError, match="/flash/drivers holds files that are not firmware"):
        deploy.deploy(build_dir, "/dev/fake", log=lambda _: None, watch_s=2)
    assert (fs / "drivers" / "notes.txt").read_text() == "mine\n"


def test_without_frozen_firmware_all_files_go_and_the_image_is_suggested(
    build_dir, tmp_path, monkeypatch, capsys
):
    fs = tmp_path / "flash"
    fs.mkdir()
    _fake(monkeypatch, fs)
    lines = []
    result = deploy.deploy(build_dir, "/dev/fake", log=lines.append, watch_s=2)
    n_files = len(build.load_manifest(build_dir)["files"])
    assert result["frozen"] is None and len(result["written"]) == n_files
    assert build.NATIVE_PATH in result["written"]
    assert any(f"no frozen firmware: deploying all {n_files} files" in line
               and "make image, make flash-image" in line for line in lines)  # fmt: skip
    _fake(monkeypatch, tmp_path / "empty")
    (tmp_path / "empty").mkdir()
    assert main(["deploy", "--port", "/dev/fake", "--flash-kb", "48"]) == 1
    err = capsys.readouterr().err
    assert "does not fit a 48 KB flash filesystem" in err and "make image" in err


def test_the_firmware_runs_from_the_frozen_image_on_the_virtual_board(build_dir, tmp_path):
    virtual_board = pytest.importorskip("host_emulator.virtual_board")
    frozen = tmp_path / "frozen"
    ident = fwid.frozen_layout(frozen)
    assert (frozen / "nav.py").is_file() and (frozen / "drivers" / "bmi055.py").is_file()
    with virtual_board.VirtualBoard(
        tmp_path / "flash", realtime=False, duration_s=30.0, frozen_dir=frozen
    ) as vb:
        result = deploy.deploy(build_dir, vb.port, frames_port=vb.rs485_port, log=lambda _: None)
        assert sorted(p.name for p in vb.fs_dir.iterdir()) == ["lib", "main.py"]
        assert [p.name for p in (vb.fs_dir / "lib").iterdir()] == ["navk.mpy"]
    assert result["frozen"]["crc32"] == ident["crc32"]
    assert result["written"] == ["lib/navk.mpy", "main.py"]  # the x64 build: the VM's arch
    assert "ins: running" in result["console"] and result["frames"] >= 3
    assert "kernels: native" in result["console"]
