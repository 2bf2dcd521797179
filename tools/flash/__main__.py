"""`python -m tools.flash build|deploy|console|config|image`: see docs/deploy.md and
docs/image.md.

Usage errors exit with status 2, failures with status 1 and one paragraph saying what to do.
"""

import argparse
import pathlib
import sys
import tempfile

from common.errors import os_error_text, quiet_broken_pipe, write_atomic
from tools.flash.errors import FlashError


def _config_module():
    from common import firmware_env

    firmware_env.install()
    import config

    return config


def _build(args):
    from tools.flash import build

    manifest = build.build(args.out, args.flash_kb, args.strip_lines)
    print(f"built {args.out}: {build.summary(manifest)}")
    print(
        "with an image that carries the firmware frozen (make image, make flash-image) only "
        "main.py, lib/navk.mpy and ins.cfg go to the filesystem: its size is then no limit "
        "(docs/image.md)"
    )
    build.check_budget(manifest)
    print(f"fits the {args.flash_kb} KB budget: {args.out}/manifest.json")
    return 0


def _decode_config(data, what, advice):
    """The BoardConfig in a configuration file's bytes; FlashError naming `what` otherwise."""
    from common.proto import config as board_config

    try:
        return board_config.decode(data)
    except board_config.ConfigError as e:
        raise FlashError(f"{what} is not a valid configuration file: {e}. {advice}") from None


def _read_config_file(path):
    """(bytes, BoardConfig) of a local configuration file."""
    from common.proto import config as board_config

    try:
        data = board_config.read_file(path)
    except board_config.ConfigError as e:
        raise FlashError(f"{e}.") from None
    cfg = _decode_config(
        data, path, "Create one with `python -m tools.flash config set --file FILE NAME=VALUE ...`."
    )
    return data, cfg


def _merged_config(changes, config):
    """config_merge for deploy --set: the changes applied to a configuration file's bytes
    (--config's, else the board's; None or one the firmware ignores: the defaults)."""

    def merge(base):
        cfg = config.BoardConfig()
        if base is not None:
            try:
                cfg = _decode_config(base, "the configuration to change", "")
            except FlashError as e:
                print(f"{e}It is replaced by the defaults and the changes.")
        cfg.apply(changes)
        return _written(cfg)[0]

    return merge


def _written(cfg):
    """(bytes, BoardConfig read back from them) of a changed configuration, checked as the board
    checks it when it loads the file: its float32s, not the Python doubles typed (proto/config.py
    `written`); FlashError if the board would refuse it."""
    from common.proto import config as board_config

    data, back, problem = board_config.written(cfg)
    if problem:
        raise FlashError(f"invalid setting: {problem}. Nothing was written.")
    return data, back


def _deploy(args):
    from tools.flash import build, deploy

    config_bytes, cfg = _read_config_file(args.config) if args.config else (None, None)
    merge = None
    if args.set:
        config = _config_module()
        changes = [_parse_setting(x, config) for x in args.set]
        merge = _merged_config(changes, config)
        # checked here, before the board is touched: on --config's file, else on the defaults
        checked = config.decode(merge(config_bytes))
        if cfg is not None:  # the output baud the frames check listens at
            cfg = checked
    if args.dry_run:
        print(_STOPS_NOTE.format(port=args.port, what="compare its files"), flush=True)
    with tempfile.TemporaryDirectory(prefix="ins-build-") as tmp:
        manifest = build.build(tmp, args.flash_kb or build.DEFAULT_FLASH_KB, args.strip_lines)
        print(
            f"built {len(manifest['files'])} files, {manifest['total_bytes']} bytes "
            f"({manifest['mpy_cross']['version']})"
        )
        frames_baud = 460800
        if cfg is not None:
            frames_baud = cfg.output_baud
        result = deploy.deploy(
            tmp,
            args.port,
            args.baud,
            config_bytes=config_bytes,
            config_merge=merge,
            frames_port=args.frames_port,
            frames_baud=frames_baud,
            dry_run=args.dry_run,
            watch_s=args.watch,
            check_budget=(lambda: build.check_budget(manifest)) if args.flash_kb else None,
        )
    if result.get("dry_run"):
        print("dry run: nothing written" + (
            "; the firmware was stopped to read the board and restarted (a soft reset: it "
            "aligns again)" if result.get("restarted") else ""))  # fmt: skip
    else:
        print("deploy OK: the firmware is running")
    return 0


def _image(args):
    from tools.flash import dfu
    from tools.image.boards import BOARDS, DEFAULT_BOARD

    board = BOARDS[args.board or DEFAULT_BOARD]
    if args.file:
        path = pathlib.Path(args.file)
    else:
        from tools.image.build import OUT_ROOT

        path = OUT_ROOT / board.name / "firmware.dfu"
        if not path.is_file():
            raise FlashError(
                f"no image for {board.name} at {path}: build it first with `make image "
                f"BOARD={board.name}` (python -m tools.image build --board {board.name})."
            )
    dfu.flash(path, board=None if args.file else board)
    print(
        "flash-image OK: the board runs the new image. Now `make deploy PORT=...` puts "
        "main.py (and ins.cfg) on its filesystem."
    )
    return 0


def _print_config(cfg, config):
    from common.proto import config as board_config

    for _rid, name, _kind, _n, _default in config._SCHEMA:
        print(f"{name} = {board_config.format_setting(getattr(cfg, name))}")


def _parse_setting(text, config):
    """(name, value) of a NAME=VALUE (common/proto/config.py's parser, which `replay
    --set` shares)."""
    from common.proto import config as board_config

    try:
        return board_config.parse_setting(text)
    except board_config.ConfigError as e:
        raise FlashError(str(e)) from None


def _console(args):
    """The board's console: mpremote's `repl` on the port, as a MicroPython user knows it. The
    firmware keeps running and what it prints shows; Ctrl-C stops it, Ctrl-D restarts it,
    Ctrl-] leaves."""
    import os

    from tools.flash import deploy

    deploy.open_port(args.port, args.baud).close()  # our message for a missing or busy port
    print(
        f"console on {args.port} (mpremote repl): Ctrl-C stops the firmware, Ctrl-D restarts "
        "it (a soft reset), Ctrl-] leaves",
        file=sys.stderr,
        flush=True,
    )
    # mpremote in this process's place: Ctrl-C is the board's, not a Python of ours to stop
    os.execv(sys.executable, [sys.executable, "-m", "mpremote", "connect", args.port, "repl"])


def _config(args):
    config = _config_module()
    from tools.flash import deploy

    if args.action == "set" and _asks_help(args.settings):
        from common.proto import config as board_config

        board_config.print_catalogue("config set")
        return 0
    if args.action == "get":
        if args.file:
            data, cfg = _read_config_file(args.file)
            print(f"# {args.file}")
        else:
            note = _STOPS_NOTE.format(port=args.port, what="read /flash/ins.cfg")
            print(note, file=sys.stderr, flush=True)
            data = deploy.read_config(args.port, args.baud)
            source = f"{args.port}:/flash/ins.cfg"
            if data is None:
                print(f"# {source}: no configuration file; the firmware uses these defaults")
                cfg = config.BoardConfig()
            else:
                cfg = _decode_config(
                    data, source, "The firmware ignores it and uses the defaults; write a new "
                    "one with `config set` or deploy --config.",
                )  # fmt: skip
                print(f"# {source}")
        if args.out and data is not None:
            write_atomic(args.out, data)
        _print_config(cfg, config)
        return 0
    # set
    changes = [_parse_setting(s, config) for s in args.settings]
    if args.file:
        # a device or a pipe (/dev/full) is written, not read: it holds no configuration
        path = pathlib.Path(args.file)
        cfg = _read_config_file(path)[1] if path.is_file() else config.BoardConfig()
    else:
        data = deploy.read_config(args.port, args.baud)
        cfg = config.BoardConfig()
        if data is not None:
            try:
                cfg = _decode_config(data, "the board's /flash/ins.cfg", "")
            except FlashError as e:  # the firmware ignores it: replaced by defaults + changes
                print(
                    f"{e}The firmware ignored it; it is replaced by the defaults and the changes."
                )
    cfg.apply(changes)
    data, cfg = _written(cfg)  # cfg: what the board reads from the file (its float32s)
    if args.file:
        write_atomic(args.file, data)
        print(f"wrote {args.file} ({len(data)} bytes); deploy it with deploy --config")
    else:
        deploy.write_config(args.port, args.baud, data)
        print("a soft reset applies it: the board was soft-reset and loads it now")
    from common.proto import config as board_config

    for name, value in changes:
        text = board_config.format_setting(getattr(cfg, name) if value is not None else None)
        print(f"{name} = {text}")
    return 0


def _parser():
    p = argparse.ArgumentParser(
        prog="python -m tools.flash",
        description="Build the firmware and deploy it to a board; flash a firmware image.",
    )
    sub = p.add_subparsers(dest="command", required=True)
    b = sub.add_parser("build", help="compile firmware/ with mpy-cross and check the budget")
    b.add_argument("--out", required=True, help="output directory")
    b.add_argument("--flash-kb", type=_positive, default=48, help="filesystem size (48)")
    b.add_argument("--strip-lines", action="store_true", help="mpy-cross -X no-source-lines")
    b.set_defaults(func=_build)
    d = sub.add_parser("deploy", help="copy the firmware to a board over its USB REPL")
    d.add_argument("--port", required=True, help=PORT_HELP)
    d.add_argument("--baud", type=_positive, default=115200, help=BAUD_HELP)
    d.add_argument("--config", help="configuration file to upload as /flash/ins.cfg")
    d.add_argument("--flash-kb", type=_positive, help="check the build against this budget")
    d.add_argument("--frames-port", help="RS485 port: confirm frames arrive after the reset")
    d.add_argument(
        "--set", nargs="+", metavar="NAME=VALUE",
        help="change settings of the configuration deployed (--config's, else the board's), "
        "e.g. raw_record=1 to record sessions that replay (docs/sessions.md)",
    )  # fmt: skip
    d.add_argument(
        "--dry-run", action="store_true",
        help="compare and report, write nothing (a running firmware is restarted after)",
    )  # fmt: skip
    d.add_argument("--strip-lines", action="store_true", help="mpy-cross -X no-source-lines")
    d.add_argument("--watch", type=float, default=15.0, help="seconds to wait for the firmware")
    d.set_defaults(func=_deploy)
    from tools.image.boards import BOARDS, DEFAULT_BOARD

    i = sub.add_parser(
        "image", help="write a MicroPython image with the firmware frozen (make image) over DFU"
    )
    which = i.add_mutually_exclusive_group()
    which.add_argument(
        "--board", choices=sorted(BOARDS), help=f"flash out/image/BOARD/firmware.dfu "
        f"({DEFAULT_BOARD})"
    )  # fmt: skip
    which.add_argument("--file", help="a .dfu file to flash instead")
    i.set_defaults(func=_image)
    k = sub.add_parser(
        "console", help="the firmware's console (mpremote repl): what it prints, Ctrl-C/Ctrl-D"
    )
    k.add_argument("--port", required=True, help=PORT_HELP)
    k.add_argument("--baud", type=_positive, default=115200, help=BAUD_HELP)
    k.set_defaults(func=_console)
    c = sub.add_parser("config", help="read or change the persisted configuration")
    csub = c.add_subparsers(dest="action", required=True)
    helps = {
        "get": "print the configuration of a board (/flash/ins.cfg) or of a file",
        "set": "change settings on a board (it is soft-reset to load them) or in a file",
    }
    for name in ("get", "set"):
        a = csub.add_parser(name, help=helps[name], description=helps[name])
        where = a.add_mutually_exclusive_group()  # required, but not by `set help`: main
        where.add_argument("--port", help=PORT_HELP)
        where.add_argument("--file", help="a local configuration file instead of a board")
        a.add_argument("--baud", type=_positive, default=115200, help=BAUD_HELP)
        if name == "get":
            a.add_argument("--out", help="also save the board's file here")
        else:
            a.add_argument(
                "settings", nargs="*", metavar="NAME=VALUE",
                help="settings to change; `help` lists them with their defaults and ranges",
            )  # fmt: skip
        a.set_defaults(func=_config, parser=a)
    return p


# A file on the board is read through its raw REPL, which a running firmware does not serve:
# the REPL reads the port only once main.py has ended, and Ctrl-C is what ends it (docs/deploy.md)
_STOPS_NOTE = (
    "note: to {what}, the firmware on {port} stops (Ctrl-C: the raw REPL) and is restarted "
    "after (it aligns again)"
)

PORT_HELP = "the board's USB serial port (its REPL): /dev/ttyACM0, COM4, ..."
BAUD_HELP = "the REPL's baud rate (115200; a USB CDC port ignores it)"


def _positive(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def _asks_help(settings):
    return any(s.strip().lower() == "help" for s in settings)


def _check_config_args(args):
    """argparse's error (status 2) for a `config` command line it cannot check itself: a
    board or a file is required, except by `config set help`; `set` needs a setting."""
    asks_help = args.action == "set" and _asks_help(args.settings)
    if not (args.port or args.file or asks_help):
        args.parser.error("one of the arguments --port --file is required")
    if args.action == "set" and not args.settings:
        args.parser.error("give at least one NAME=VALUE (`config set help` lists them)")


def main(argv=None):
    args = _parser().parse_args(argv)
    if args.command == "config":
        _check_config_args(args)
    try:
        return args.func(args)
    except FlashError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(
            "interrupted: run the command again (deploy only sends what differs)", file=sys.stderr
        )
        return 130
    except BrokenPipeError:  # `config get | head`
        return quiet_broken_pipe()
    except OSError as e:  # a host file: `--out` into a read-only directory, a full disk
        print(f"error: {os_error_text(e)}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
