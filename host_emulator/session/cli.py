"""`python -m host_emulator session record|replay|repair|report`: exit status 0 (done, identical), 1
(the replay differs, the firmware raised, a file or port that cannot be read or written, a
recording the disk cut short), 2 (a bad command line), as tools.flash and tools.monitor."""

import argparse
import sys
import tempfile
from pathlib import Path

from common.errors import EmulatorError
from common.proto import config as board_config
from common.proto import session_file
from host_emulator import args as cli_args
from host_emulator import runtimes
from host_emulator.display import pictures
from host_emulator.session import report as session_report
from host_emulator.session.record import record
from host_emulator.session.replay import replay


def _progress_printer():
    if not sys.stderr.isatty():
        return None
    return lambda a, b: print(f"\r{a} / {b}", end="", file=sys.stderr, flush=True)


def main(argv=None):
    """`session record SOURCE --out FILE ...` / `session replay FILE ...`: exit status 0 (done,
    identical), 1 (replay differs, the firmware raised, a failure), 2 (a bad command line)."""
    p = cli_args.Parser(
        prog="python -m host_emulator session",
        description="record a board's output; replay it through the emulator, byte for byte",
    )
    sub = p.add_subparsers(dest="command", required=True, parser_class=cli_args.Parser)
    r = sub.add_parser("record", help="capture a board's output into a session file")
    r.add_argument("source", help="serial port (/dev/ttyUSB0, COM3), named pipe, '-' or file")
    r.add_argument("--out", required=True, help="session file to write")
    r.add_argument(
        "--duration", help="stop after this many seconds (default: Ctrl-C or end of input)"
    )
    r.add_argument("--seconds", dest="duration", help=argparse.SUPPRESS)  # its old name
    r.add_argument("--baud", help="serial baud rate (default: the configuration's, else 460800)")
    r.add_argument("--config", help="the board's configuration file (or JSON), kept in the file")
    s = sub.add_parser("replay", help="replay a session through the emulator and compare")
    s.add_argument("session", help="session file (or a plain capture, with --config)")
    s.add_argument("--config", help="the board's configuration (overrides the session's)")
    s.add_argument(
        "--runtime", default="auto", choices=["auto", *runtimes.names()],
        help="where to replay: auto (default) picks the one whose arithmetic is the recording "
        "board's (cpython, bit-exact, for a board; mpy_unix for the virtual board, whose VM "
        "computes in double, compared to a tolerance)",
    )  # fmt: skip
    cli_args.add_board_option(s)
    s.add_argument("--until-gap", action="store_true", help="replay up to the first gap")
    s.add_argument(
        "--from-last-start", action="store_true",
        help="replay from the board's last start in the recording (it restarted), not its first",
    )  # fmt: skip
    s.add_argument("--out", help="directory for stimulus.bin and replayed.bin (kept)")
    s.add_argument(
        "--display", metavar="PATH",
        help="run the board's screen too and draw it: PATH.png at the end, PATH_strip.png "
        "over the replay (docs/display.md)",
    )  # fmt: skip
    f = sub.add_parser(
        "repair", help="keep what survived of a cut or damaged session file in a new one"
    )
    f.add_argument("session", help="the cut or damaged session file (it is not changed)")
    f.add_argument("--out", required=True, help="the session file to write")
    g = sub.add_parser("report", help="report.md and plots of a recording (no truth needed)")
    g.add_argument("session", help="session file (or a plain capture of the board's output)")
    g.add_argument("--out", help="directory for report.md and the plots (default: FILE-report)")
    try:
        args = p.parse_args(argv)
        if args.command == "replay" and args.runtime != "auto":
            cli_args.check_board(args.runtime, args.board)
        if args.command == "record":
            seconds = args.duration
            seconds = None if seconds is None else cli_args.positive(seconds, "--duration")
            baud = None if args.baud is None else int(cli_args.positive(args.baud, "--baud"))
        if args.command == "replay" and args.display is not None:
            pictures.check_path(args.display)
        if args.command == "repair" and Path(args.out).resolve() == Path(args.session).resolve():
            raise cli_args.UsageError("--out must be another file: the damaged one is kept")
    except (cli_args.UsageError, EmulatorError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if args.command == "record":
        return cli_args.run_reporting(lambda: _main_record(args, seconds, baud))
    if args.command == "repair":
        return cli_args.run_reporting(lambda: _main_repair(args))
    if args.command == "report":
        return cli_args.run_reporting(lambda: _main_report(args))
    return cli_args.run_reporting(lambda: _main_replay(args))


def _main_repair(args):
    s = session_file.repair(args.session, args.out)
    for line in s.problems(args.session) or [f"{args.session}: intact, nothing was lost"]:
        print(line)
    print(f"wrote {len(s.data)} captured bytes into {args.out}")
    return 0


def _main_report(args):
    out, fig = session_report.write(args.session, args.out)
    print(
        f"{fig['frames']} frames over {fig['duration_s']:.1f} s, navigating "
        f"{fig['navigating_s']:.1f} s, {fig['dropped_frames']} dropped, "
        f"{fig['starts']} start(s)"
    )
    print(f"report: {out}/report.md   plots: {out}/*.png")
    return 0


def _main_record(args, seconds, baud):
    tty = sys.stderr.isatty()

    def progress(nbytes, elapsed):
        if tty:
            print(f"\r{nbytes} bytes, {elapsed:.0f} s", end="", file=sys.stderr, flush=True)

    if tty and seconds is None:
        print("recording; Ctrl-C stops", file=sys.stderr)
    res = record(args.source, args.out, seconds, progress, args.config, baud)
    if tty:
        print(file=sys.stderr)
    print(
        f"recorded {res['bytes']} bytes in {res['seconds']:.1f} s ({res['stopped']}) into "
        f"{res['path']}"
    )
    if res["bytes"] == 0:
        print("warning: nothing was received (baud rate? wiring? is the board on?)")
    return 0


def _main_replay(args):
    progress = _progress_printer()
    display = args.display is not None
    if args.out:
        work = Path(args.out)
        res = replay(args.session, work, args.runtime, args.config, args.until_gap, progress,
                     args.from_last_start, args.board, display)  # fmt: skip
        res.stimulus.write(work / "stimulus.bin")
        (work / "replayed.bin").write_bytes(res.run.out)
    else:
        with tempfile.TemporaryDirectory(prefix="session-") as d:
            res = replay(args.session, d, args.runtime, args.config, args.until_gap, progress,
                         args.from_last_start, args.board, display)  # fmt: skip
    if progress:
        print(file=sys.stderr)
    print(res.summary())
    if display:
        cfg = board_config.from_values(board_config.run_values(res.stimulus, {"display": 1}))
        s = res.stimulus
        written = pictures.write(res.run, (cfg.display_w, cfg.display_h), s.tick_us * 1e-6,
                                 s.duration_s, args.display)  # fmt: skip
        print(f"screen: {written[0]} (the end), {written[1]} (over the replay)")
    return 0 if res.identical else 1
