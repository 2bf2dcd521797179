"""Every test sees the firmware as the board does (flat `firmware/lib` modules on the path,
the NumPy float32 backend behind the seam). `flash_build_dir`: the firmware's files as
`make build-flash` writes them, built once per session (per worker) for every test that
deploys or quotes them; the tests only read it."""

import pytest

from common import firmware_env

firmware_env.install()


@pytest.fixture(scope="session")
def flash_build_dir(tmp_path_factory):
    """A folder with `python -m tools.flash build`'s output (manifest.json and the files)."""
    from tools.flash import build

    out = tmp_path_factory.mktemp("flash-build")
    build.build(out)
    return out
