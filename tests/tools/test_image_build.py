"""python -m tools.image build: the WEACT_F411_BLACKPILL image with the firmware frozen, its
budget read from the ELF, the firmware id it carries, its three output formats, the cache, the
untouched MicroPython tree, and the errors a user meets."""

import re
import shutil
import subprocess
import zlib

import pytest

from common import toolchain
from common.firmware_env import FIRMWARE_DIR
from tools.flash import dfu
from tools.image import budget, build, fwid
from tools.image.__main__ import main

KB = 1024


def _sections(elf):
    out = subprocess.run(["arm-none-eabi-size", "-A", str(elf)], capture_output=True, text=True)
    return {p[0]: int(p[1]) for p in (ln.split() for ln in out.stdout.splitlines()) if len(p) == 3
            and p[1].isdigit()}  # fmt: skip


def _symbol(elf, name):
    out = subprocess.run(["arm-none-eabi-nm", str(elf)], capture_output=True, text=True).stdout
    return int(re.search(rf"^([0-9a-f]+) \w {name}$", out, re.MULTILINE).group(1), 16)


def test_the_image_is_within_budget_by_the_elf(weact_image):
    report, out, lines, _ = weact_image
    fig = report["figures"]
    sec = _sections(report["elf"])
    # the code region holds .text, .ARM and .data's initial values: what firmware1.bin is
    code = sec[".text"] + sec[".ARM"] + sec[".data"]
    assert fig["code_bytes"] == code
    obj = build.BUILD_ROOT / "WEACT_F411_BLACKPILL" / "obj"
    assert fig["code_bytes"] == (obj / "firmware1.bin").stat().st_size
    # our layout (tools/image/boards/stm32f411_fs48.ld): the code from sector 4, the
    # filesystem in sectors 1-3
    assert fig["code_region_origin"] == 0x08010000 and fig["code_region_bytes"] == 448 * KB
    assert fig["filesystem_origin"] == 0x08004000 and fig["filesystem_bytes"] == 48 * KB
    assert fig["flash_bytes"] == 512 * KB
    assert 250 * KB < fig["code_bytes"] <= 448 * KB - budget.MIN_CODE_FREE_BYTES  # 286,736 B
    assert fig["code_free_bytes"] >= 64 * KB  # the goal: 172,016 B measured
    assert fig["vector_sector_used_bytes"] == sec[".isr_vector"] + sec[".isr_extratext"] <= 16 * KB
    assert fig["flash_programmed_bytes"] == fig["code_bytes"] + fig["vector_sector_used_bytes"]
    assert fig["static_ram_bytes"] == sec[".data"] + sec[".bss"]
    # RAM = static + heap + stack (+ 8 bytes reserved above the stack)
    assert fig["ram_bytes"] == 112 * KB and fig["stack_bytes"] == 16 * KB
    assert 0 <= fig["ram_bytes"] - fig["static_ram_bytes"] - fig["heap_bytes"] - 16 * KB <= 16
    assert fig["heap_bytes"] >= budget.MIN_HEAP_BYTES  # measured 89,568 B
    assert report["problems"] == []
    # the frozen firmware: its bytecode (the .mpy files makemanifest compiled) plus qstrs
    # (of the modules frozen now: frozen_mpy/ keeps the .mpy of a module no longer frozen)
    names = [name for name, _p, _v in fwid.frozen_sources()] + ["fwid.py"]
    mpy = sum((obj / "frozen_mpy" / (name[:-3] + ".mpy")).stat().st_size for name in names)
    assert 1.0 < fig["frozen_bytes"] / mpy < 1.3  # measured 76,659 B for 70,048 B of .mpy
    printed = "\n".join(lines)
    assert f"{fig['code_bytes']:,} B of 458,752 (448 KB from 0x08010000, sectors 4-7)" in printed
    assert "sectors 1-3 hold the 48 KB filesystem" in printed
    assert f"{fig['heap_bytes']:,} B" in printed


def test_the_image_carries_the_firmware_and_its_id(weact_image):
    report, out, _, _ = weact_image
    flat = (out / "firmware.bin").read_bytes()
    at = _symbol(report["elf"], "mp_frozen_names") - dfu.FLASH_BASE
    names = flat[at : flat.index(b"\0\0", at)].decode().split("\0")
    frozen = {name for name, _path, _v in fwid.frozen_sources()}
    assert set(names) == frozen | {"fwid.py"}
    assert {"app.py", "board.py", "nav.py", "drivers/bmi055.py"} <= frozen
    ident = fwid.host_id()
    assert report["firmware"]["crc32"] == ident["crc32"]
    assert ident["crc32"].encode() in flat  # the frozen fwid's FIRMWARE_CRC32 string
    # every firmware file but main.py and the Python reference kernels (navk runs instead)
    left_out = ("main.py", "manifest.py", "nav_kern.py", "yaw_gsf.py", "gnss_kern.py")
    want = sum(1 for p in FIRMWARE_DIR.rglob("*.py") if p.name not in left_out)
    assert ident["files"] == want == len(frozen)
    assert not {"nav_kern.py", "yaw_gsf.py", "drivers/gnss_kern.py"} & set(names)
    gen = (build.BUILD_ROOT / "WEACT_F411_BLACKPILL" / "gen" / "fwid.py").read_text()
    assert f"FIRMWARE_CRC32 = '{ident['crc32']}'" in gen and "BOARD = 'WEACT_F411_BLACKPILL'" in gen


def _read_hex(path):
    """{address: byte} of an Intel HEX file (record checksums checked)."""
    memory, base = {}, 0
    for line in path.read_text().split():
        n, addr, kind = int(line[1:3], 16), int(line[3:7], 16), int(line[7:9], 16)
        data = bytes.fromhex(line[9 : 9 + 2 * n])
        assert sum(bytes.fromhex(line[1:])) & 0xFF == 0
        if kind == 4:
            base = int.from_bytes(data, "big") << 16
        elif kind == 0:
            memory.update((base + addr + i, b) for i, b in enumerate(data))
    return memory


def test_dfu_hex_and_bin_hold_the_same_bytes(weact_image):
    _, out, _, _ = weact_image
    memory = _read_hex(out / "firmware.hex")  # straight from the ELF (objcopy -O ihex)
    parts = dfu.read_image(out / "firmware.dfu")
    assert [a for a, _ in parts] == [0x08000000, 0x08010000]  # sector 0, the code from sector 4
    for addr, data in parts:
        n = 0
        while addr + n in memory:
            n += 1
        assert data[:n] == bytes(memory[addr + i] for i in range(n))
        pad = len(data) - n  # tools/dfu.py pads each element to 8 bytes with zeros
        assert len(data) % 8 == 0 and pad < 8 and data[n:] == bytes(pad)
    flat = (out / "firmware.bin").read_bytes()
    assert len(flat) == max(memory) + 1 - dfu.FLASH_BASE
    assert all(flat[a - dfu.FLASH_BASE] == b for a, b in memory.items())
    gaps = [flat[i] for i in range(len(flat)) if dfu.FLASH_BASE + i not in memory]
    assert set(gaps) == {0xFF} and len(gaps) == len(flat) - len(memory)


def test_the_build_is_cached_and_never_writes_into_the_micropython_tree(weact_image, tmp_path):
    _, _, _, changes = weact_image
    assert changes == []  # whether the session's build was cold (CI) or cached
    src = toolchain.micropython_dir()
    before = build.snapshot(src)
    lines = []
    again = build.build("WEACT_F411_BLACKPILL", tmp_path, log=lines.append)
    assert build.tree_changes(before, build.snapshot(src)) == []
    assert again["rebuilt"] is False and again["seconds"] < 20  # measured 2 s
    assert any("up to date: nothing to rebuild" in line for line in lines)
    assert again["figures"] == weact_image[0]["figures"]


def test_the_firmware_id_is_a_crc_over_names_sizes_and_bytes():
    one = zlib.crc32(b"a.py\x001\x00x")
    assert fwid.firmware_crc([("a.py", b"x")]) == f"{one:08x}"
    two = [("b.py", b"yy"), ("a.py", b"x")]
    expect = zlib.crc32(b"b.py\x002\x00yy", one)
    assert fwid.firmware_crc(two) == f"{expect:08x}"  # in order of the names
    assert fwid.firmware_crc([("a.py", b"xb.py")]) != fwid.firmware_crc([("a.py", b"x"),
                                                                       ("b.py", b"")])  # fmt: skip


def test_the_board_answer_is_parsed():
    got = fwid.parse_board_answer("FWID 8c8e949f 0.1.0 1.28.0 WEACT_F411_BLACKPILL\r\n")
    assert got == {"crc32": "8c8e949f", "version": "0.1.0", "micropython": "1.28.0",
                   "board": "WEACT_F411_BLACKPILL"}  # fmt: skip
    assert fwid.parse_board_answer("FWID -\r\n") is None


def test_over_budget_figures_are_named():
    fig = {
        "code_bytes": 400_000,
        "code_region_bytes": 393_216,
        "vector_sector_used_bytes": 100,
        "vector_sector_bytes": 16_384,
        "heap_bytes": 60_000,
        "static_ram_bytes": 40_000,
    }
    problems = budget.problems(fig)
    assert problems[0] == "the code needs 400,000 bytes but the code region holds 393,216 (384 KB)"
    assert "the heap is 60,000 bytes, under the 64 KB" in problems[1]


def test_under_32_kb_left_in_the_code_region_fails_the_build():
    fig = {"code_bytes": 448 * KB - 32 * KB + 1, "code_region_bytes": 448 * KB,
           "vector_sector_used_bytes": 100, "vector_sector_bytes": 16_384,
           "heap_bytes": 92_572, "static_ram_bytes": 5_724}  # fmt: skip
    assert budget.problems(fig) == [
        "only 32,767 bytes of the 448 KB code region would be left, under the 32 KB kept free "
        "(the code needs 425,985)"
    ]
    fig["code_bytes"] -= 1  # exactly 32 KB left: fits
    assert budget.problems(fig) == []


def test_a_build_over_its_budget_fails_in_one_line_and_writes_no_image(
    weact_image, monkeypatch, tmp_path, capsys
):
    """make image over budget: one line on stderr, status 1, budget.json written, no image
    files (an older one is deleted: it is never flashed by mistake)."""
    real = budget.measure

    def tight(elf, map_path):
        fig = real(elf, map_path)
        fig["code_region_bytes"] = fig["code_bytes"] + 20 * KB  # 20 KB would be left
        fig["code_free_bytes"] = 20 * KB
        return fig

    monkeypatch.setattr(budget, "measure", tight)
    (tmp_path / "firmware.dfu").write_bytes(b"an older image")
    assert main(["build", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("error: the image for WEACT_F411_BLACKPILL is over budget: only 20,480 "
                          "bytes of the ")  # fmt: skip
    assert "under the 32 KB kept free" in err and "Traceback" not in err
    assert not (tmp_path / "firmware.dfu").exists() and (tmp_path / "budget.json").is_file()


def test_a_linker_overflow_is_reported_as_over_budget(tmp_path):
    log = "LINK firmware.elf\nld: region `FLASH_TEXT' overflowed by 1234 bytes\ncollect2: error\n"
    e = build.explain_failure(log, tmp_path / "build.log", "WEACT_F411_BLACKPILL")
    assert "over budget" in str(e) and "FLASH_TEXT by 1,234 bytes" in str(e)
    assert "448 KB code region" in str(e) and str(tmp_path / "build.log") in str(e)


def test_a_build_error_names_the_log_and_quotes_its_tail(tmp_path, capsys):
    board = tmp_path / "NUCLEO_F411RE"
    shutil.copytree(build.BOARDS["NUCLEO_F411RE"].board_dir, board)
    for f in build.shared_board_files(build.BOARDS["NUCLEO_F411RE"].board_dir):
        shutil.copy(f, tmp_path)  # the features header and the linker script beside it
    with open(board / "pins.csv", "a") as f:
        f.write("D99,PZ99\n")
    with pytest.raises(build.ImageError) as e:
        build.build("NUCLEO_F411RE", tmp_path / "out", log=lambda _: None,
                    build_root=tmp_path / "b", board_dir=board)  # fmt: skip
    log = tmp_path / "b" / "NUCLEO_F411RE" / "build.log"
    assert f"full log: {log}" in str(e.value)
    assert "Invalid cpu pin name 'PZ99'" in str(e.value) and log.is_file()
    assert not (tmp_path / "out" / "firmware.dfu").exists()


def test_a_wrong_micropython_dir_is_said_plainly(monkeypatch, tmp_path, capsys):
    monkeypatch.setenv("MICROPY_DIR", str(tmp_path / "nowhere"))
    assert main(["build", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "no MicroPython source tree at" in err and "MICROPY_DIR" in err
    assert "Traceback" not in err


def test_a_missing_toolchain_stops_the_build_with_ensures_message(monkeypatch, tmp_path, capsys):
    def missing():
        raise toolchain.ToolchainError(
            "toolchain: missing gcc-arm-none-eabi; install them with\n"
            "  sudo apt-get install gcc-arm-none-eabi=15:12.2.rel1-1"
        )

    monkeypatch.setattr(toolchain, "ensure", missing)
    assert main(["build", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "missing gcc-arm-none-eabi" in err and "sudo apt-get install" in err


def test_an_unknown_board_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as e:
        main(["build", "--board", "PYBV11"])
    assert e.value.code == 2
    assert "invalid choice: 'PYBV11'" in capsys.readouterr().err


def test_the_emulated_cortex_m4f_gives_the_firmware_this_images_heap(weact_image):
    """runtimes/m4f sizes the firmware's free heap as the image's: keep them equal."""
    from host_emulator.runtimes.m4f import build as m4f_build

    assert weact_image[0]["figures"]["heap_bytes"] == m4f_build.BOARD_HEAP_BYTES


def test_the_image_has_no_fused_multiply_add(weact_image):
    """Built with common.toolchain.C_FLOAT_FLAGS, as the emulated Cortex-M4F is."""
    assert toolchain.fused_multiply_adds(weact_image[0]["elf"]) == []


def _git(*args, cwd):
    import subprocess

    subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True,
                   env={"GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME":
                        "t", "GIT_COMMITTER_EMAIL": "t@t", "PATH": "/usr/bin:/bin"})  # fmt: skip


def test_the_build_pins_micropythons_version_whatever_repository_holds_the_tree(tmp_path):
    """py/makeversionhdr.py names a build after `git describe` of the repository the tree is
    in: a copy vendored inside another project would say that project's commit. The build
    passes the tree's own version (and its own commit only when the tree is a repository of
    its own)."""
    from common import toolchain

    src = toolchain.micropython_dir() / "py" / "mpconfig.h"
    outer = tmp_path / "project"
    tree = outer / "vendor" / "micropython"
    (tree / "py").mkdir(parents=True)
    (tree / "py" / "mpconfig.h").write_text(src.read_text())
    _git("init", "-q", cwd=outer)
    _git("add", ".", cwd=outer)
    _git("commit", "-q", "-m", "x", cwd=outer)
    _git("tag", "v9.9.9", cwd=outer)
    env = toolchain.version_env(tree)
    assert env["MICROPY_GIT_TAG"] == "v1.28.0"  # not the outer repository's v9.9.9
    assert "MICROPY_GIT_HASH" not in env
    _git("init", "-q", cwd=tree)
    _git("add", ".", cwd=tree)
    _git("commit", "-q", "-m", "x", cwd=tree)
    env = toolchain.version_env(tree)
    assert env["MICROPY_GIT_TAG"] == "v1.28.0"
    assert len(env["MICROPY_GIT_HASH"]) >= 7


def test_a_changed_board_definition_starts_the_build_afresh(tmp_path):
    """make remakes the qstrs when mpconfigboard.h changes but not the module table (the link
    then fails on a module turned off), and relinks nothing for a changed linker script: the
    build key holds the content of the board's files and of the shared ones beside them."""
    boards = tmp_path / "boards"
    board = boards / "B"
    board.mkdir(parents=True)
    (board / "mpconfigboard.h").write_text("#define X (1)\n")
    (boards / "shared.h").write_text("// shared\n")
    (boards / "layout.ld").write_text("/* layout */\n")
    (boards / "notes.txt").write_text("not part of a board definition\n")
    obj = tmp_path / "build" / "obj"
    lines = []

    def check():
        obj.mkdir(parents=True, exist_ok=True)
        (obj / "x.o").write_text("object")
        build._check_build_key(tmp_path / "build", obj, "tree", "1.28.0", "B", board,
                               lines.append)  # fmt: skip
        return (obj / "x.o").exists()

    check()
    key = (tmp_path / "build" / "key.json").read_text()
    assert all(name in key for name in ('"mpconfigboard.h"', '"../shared.h"', '"../layout.ld"'))
    assert "notes.txt" not in key
    assert check()  # nothing changed: obj/ kept
    for path, text in ((board / "mpconfigboard.h", "#define X (0)\n"),
                       (boards / "shared.h", "// changed\n"),
                       (boards / "layout.ld", "/* moved */\n")):  # fmt: skip
        path.write_text(text)
        assert not check(), path.name  # emptied: a clean build
        assert "the board definition" in lines[-1]
        assert check()
    (boards / "notes.txt").write_text("changed\n")
    assert check()


def test_sizes_tell_where_the_bytes_go(weact_image):
    """python -m tools.image sizes: the code region by object file adds up to the code, the
    frozen firmware module by module to frozen_content.o's share, and the module table holds
    what the firmware and the board tools import and none of what they never use."""
    from tools.image import sizes

    report = weact_image[0]
    fig = sizes.measure(build.BUILD_ROOT / "WEACT_F411_BLACKPILL" / "obj")
    objects = fig["objects"]
    # input sections only: the alignment between them is the rest (measured 184 B)
    assert 0 <= report["figures"]["code_bytes"] - sum(objects.values()) < 1024
    assert objects["frozen_content.o"] == report["figures"]["frozen_bytes"]
    assert sum(fig["frozen"].values()) == objects["frozen_content.o"]
    assert {"nav", "app", "drivers_gnss", "fwid"} <= fig["frozen"].keys()
    used = {"array", "binascii", "deflate", "gc", "machine", "math", "micropython", "os", "stm",
            "struct", "sys", "time", "uctypes", "vfs"}  # fmt: skip
    assert used <= set(fig["modules"])
    unused = {"framebuf", "heapq", "re", "json", "hashlib", "random", "cmath", "select",
              "socket", "network", "_asyncio", "_onewire"}  # fmt: skip
    assert unused.isdisjoint(fig["modules"])
    for name in ("lib/littlefs/lfs2.o", "py/emitnthumb.o", "py/emitinlinethumb.o",
                 "extmod/modframebuf.o", "extmod/machine_i2c.o", "usbdev/class/src/"
                 "usbd_msc_scsi.o"):  # fmt: skip
        assert name not in objects, name
    lines = sizes.report(fig, top=5)
    assert lines[1] == "by object file (the 5 largest):" and "frozen_content.o" in lines[2]
    diff = sizes.report(fig, 5, {**fig, "objects": {**objects, "py/vm.o": objects["py/vm.o"] - 8},
                                 "modules": fig["modules"] + ["framebuf"]})  # fmt: skip
    assert "against the saved build: +8 B" in diff[1] and "py/vm.o" in diff[3]
    assert diff[-1] == "built-in modules left out: framebuf"
