"""The firmware image the image, flash and deploy tests share: WEACT_F411_BLACKPILL built once
per session into build/image (cached there between runs; a clean clone builds it from scratch,
about a minute), copied to a temporary output folder. No skip: without the toolchain the
build fails, as it must under CI (common.toolchain.ensure installs it when it may)."""

import pytest

from common import toolchain
from tools.image import build


@pytest.fixture(scope="session")
def weact_image(tmp_path_factory):
    """(report, output folder, log lines, source-tree changes) of the WEACT image build."""
    out = tmp_path_factory.mktemp("image")
    lines = []
    src = toolchain.micropython_dir()
    before = build.snapshot(src)
    report = build.build("WEACT_F411_BLACKPILL", out, log=lines.append)
    changes = build.tree_changes(before, build.snapshot(src))
    return report, out, lines, changes
