"""The private consts nav_kern.py, nav_aid.py and nav_align.py repeat from nav.py,
gnss_kern.py from gnss.py, and app.py and status_page.py from frame.py, records.py, nav.py,
geo.py and status_page.py, are generated (common/native/const_copies.py): fresh, equal to the
owner's values, and only what each uses."""

import pytest

from common.firmware_env import import_module
from common.native import const_copies


def test_the_copies_are_what_the_generator_writes():
    for path, text in const_copies.generated().items():
        assert path.read_text() == text, f"{path.name}: run `python -m common.native.layout`"


@pytest.mark.parametrize("module, owner", const_copies.COPIES)
def test_every_copied_const_has_the_owners_value(module, owner):
    """Read through CPython (a const is a plain attribute there), not through the generator."""
    own = import_module(owner)
    mod = import_module(module)
    copied = 0
    for name in vars(mod):
        if not name.startswith("_") or name.startswith("__"):
            continue
        for owner_name in (name, name[1:]):
            if owner_name in vars(own) and isinstance(getattr(own, owner_name), int):
                assert getattr(mod, name) == getattr(own, owner_name), (module, name)
                copied += 1
                break
    assert copied >= 1, (module, owner)


def test_the_hand_written_index_agrees():
    """The one index taken from another module that is not a copy (a sum), written by hand
    with its reason."""
    eskf = import_module("eskf")
    assert import_module("nav_align")._IX_YAW == eskf.IX_ATT + 2


def _lib(tmp_path, monkeypatch, owner, target):
    (tmp_path / "own.py").write_text(owner)
    (tmp_path / "use.py").write_text(target)
    monkeypatch.setattr(const_copies, "_path", lambda m: tmp_path / (m + ".py"))


BEGIN = "# ---- own.py's consts used here: `python -m common.native.layout` writes them ----\n"
END = "# ---- end of own.py's consts ----\n"
OWNER = "PUB = const(1)\n_HEX = const(0x1F)  # a comment\n_NEG = const(-3)\n_ONLY_SAID = const(4)\n"


def test_a_block_takes_the_names_used_in_the_owners_order_and_literals(tmp_path, monkeypatch):
    code = "def f(a):\n    # _ONLY_SAID in a comment\n    return a[_NEG] + a[_HEX] + _PUB\n"
    _lib(tmp_path, monkeypatch, OWNER, "x = 1\n" + BEGIN + "_STALE = const(9)\n" + END + code)
    out = const_copies.generate("use", "own")
    block = out.split(BEGIN)[1].split(END)[0]
    assert block == "_PUB = const(1)\n_HEX = const(0x1F)\n_NEG = const(-3)\n"
    assert out.endswith(END + code)


def test_a_hand_copy_a_missing_marker_and_a_split_const_are_errors(tmp_path, monkeypatch):
    _lib(tmp_path, monkeypatch, OWNER, BEGIN + END + "_HEX = const(0x1F)\ny = _HEX\n")
    with pytest.raises(const_copies.CopyError, match="defines _HEX by hand"):
        const_copies.generate("use", "own")
    _lib(tmp_path, monkeypatch, OWNER, BEGIN + "y = _HEX\n")
    with pytest.raises(const_copies.CopyError, match="needs the lines"):
        const_copies.generate("use", "own")
    _lib(tmp_path, monkeypatch, "_LONG = const(\n    1\n)\n", BEGIN + END + "y = _LONG\n")
    with pytest.raises(const_copies.CopyError, match="on one line"):
        const_copies.generate("use", "own")


def test_several_owners_a_block_each_and_a_name_from_one_only(tmp_path, monkeypatch):
    (tmp_path / "own.py").write_text(OWNER)
    (tmp_path / "two.py").write_text("_HEX = const(0x1F)\nTWO = const(2)\n")
    begin2 = BEGIN.replace("own.py", "two.py")
    end2 = END.replace("own.py", "two.py")
    (tmp_path / "use.py").write_text(BEGIN + END + begin2 + end2 + "y = _PUB + _TWO\n")
    monkeypatch.setattr(const_copies, "_path", lambda m: tmp_path / (m + ".py"))
    monkeypatch.setattr(const_copies, "COPIES", (("use", "own"), ("use", "two")))
    (text,) = const_copies.generated().values()
    assert text == BEGIN + "_PUB = const(1)\n" + END + begin2 + "_TWO = const(2)\n" + end2 + (
        "y = _PUB + _TWO\n"
    )
    (tmp_path / "use.py").write_text(BEGIN + END + begin2 + end2 + "y = _HEX\n")
    with pytest.raises(const_copies.CopyError, match="_HEX is defined twice"):
        const_copies.generated()
