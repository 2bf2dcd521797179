"""`python -m tools.flash build`: the board layout, the manifest, and the flash budget (the
firmware does not fit the STM32F411's internal 48 KB filesystem, and build says so)."""

import binascii
import json

import pytest

from tools.flash import build
from tools.flash.__main__ import main


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp("build")
    return out, build.build(out)


def test_layout_is_the_boards(built):
    out, manifest = built
    paths = {f["path"] for f in manifest["files"]}
    assert {"main.py", "app.mpy", "board.mpy", "lib/nav.mpy", "drivers/gnss.mpy"} <= paths
    assert not any(p.endswith(".py") and p != "main.py" for p in paths)
    assert (out / "main.py").read_bytes() == (build.FIRMWARE_DIR / "main.py").read_bytes()
    assert (out / "lib" / "nav.mpy").read_bytes()[:2] == b"M\x06"
    assert manifest["dirs"] == ["drivers", "lib"]


def test_manifest_sizes_and_crcs_match_the_files(built):
    out, manifest = built
    on_disk = json.loads((out / "manifest.json").read_text())
    assert on_disk == manifest
    for f in manifest["files"]:
        data = (out / f["path"]).read_bytes()
        assert f["size"] == len(data)
        assert int(f["crc32"], 16) == binascii.crc32(data)
    assert manifest["total_bytes"] == sum(f["size"] for f in manifest["files"])
    assert manifest["mpy_cross"]["options"] == ["-march=armv7emsp"]
    assert "mpy v6.3" in manifest["mpy_cross"]["version"]


def test_build_is_reproducible_and_independent_of_the_checkout_path(built, tmp_path):
    _, manifest = built
    again = build.build(tmp_path / "x")
    assert again["files"] == manifest["files"]
    assert b"/work" not in (tmp_path / "x" / "lib" / "nav.mpy").read_bytes()


def test_fat_geometry_of_the_f411_internal_filesystem():
    geo = build.fat_geometry(48)
    # 96 sectors: boot sector, one FAT sector, 2 sectors of root directory (32 entries, as
    # deploy formats it: tools/flash/fatfs.py), 92 clusters; the port's 512 entries: 62
    assert geo["cluster_bytes"] == 512 and geo["root_entries"] == 32
    assert geo["data_clusters"] == 92
    assert geo["fat_overhead_bytes"] == 4 * 512
    big = build.fat_geometry(4096)  # an SPI flash: the port's layout, 512 root entries
    assert big["root_entries"] == 512 and big["data_bytes"] > 4000 * 1024


def test_firmware_does_not_fit_48_kb_and_build_says_how_to_get_out(built, capsys, tmp_path):
    _, manifest = built
    assert not manifest["budget"]["fits"]
    assert manifest["budget"]["needed_clusters"] > manifest["budget"]["data_clusters"]
    assert main(["build", "--out", str(tmp_path / "b")]) == 1
    err = capsys.readouterr().err
    assert "does not fit a 48 KB" in err
    assert "--flash-kb 4096" in err and "freeze" in err
    assert "Traceback" not in err
    assert (tmp_path / "b" / "manifest.json").exists()  # written anyway, with fits: false


def test_fits_a_4_mb_spi_flash(tmp_path, capsys):
    assert main(["build", "--out", str(tmp_path), "--flash-kb", "4096"]) == 0
    assert "fits the 4096 KB budget" in capsys.readouterr().out
    assert json.loads((tmp_path / "manifest.json").read_text())["budget"]["fits"]


def test_strip_lines_is_smaller(built, tmp_path):
    _, manifest = built
    stripped = build.build(tmp_path, strip_lines=True)
    assert stripped["total_bytes"] < manifest["total_bytes"] - 2000
    assert "no-source-lines" in stripped["mpy_cross"]["options"]


@pytest.mark.parametrize(
    "argv", [[], ["build"], ["build", "--out", "x", "--flash-kb", "-3"], ["frobnicate"]]
)
def test_usage_errors_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert "usage:" in capsys.readouterr().err
