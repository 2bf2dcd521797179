"""Command-line plumbing the host's commands share: a parser that reports a mistake in one line
(`UsageError`, exit status 2, no usage dump) and the input checks every command applies alike,
so a bad scenario or duration reads the same in `run`, `parity`, `export` and the virtual board.
"""

import argparse
import sys

from common.errors import EmulatorError, FirmwareError, os_error_text, quiet_broken_pipe

MAX_DURATION_S = 24 * 3600.0


class UsageError(Exception):
    """A command line that cannot be run as given."""


class Parser(argparse.ArgumentParser):
    def error(self, message):
        # the command's name, as argparse's own line has it: "error: the following arguments
        # are required: --out" alone does not say which of a command's subcommands wants it
        raise UsageError(f"{self.prog}: {message}")


USAGE_STATUS = 2  # a command line that cannot be run, as argparse's own errors exit


def run_reporting(command):
    """command()'s exit status, with what a user must not see as a traceback said in one
    paragraph on stderr: a command line found wrong late (UsageError: 2, as argparse's), the
    firmware raised, bad input or a failed run, a file that cannot be written or read (a full
    disk, a read-only directory): 1, as tools.flash and tools.monitor; Ctrl-C (130); a closed
    output pipe (`| head`) ends it quietly (141)."""
    try:
        return command()
    except UsageError as e:
        print(f"error: {e}", file=sys.stderr)
        return USAGE_STATUS
    except (FirmwareError, EmulatorError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return quiet_broken_pipe()
    except OSError as e:  # a full disk, a read-only directory: the file and the reason
        print(f"error: {os_error_text(e)}", file=sys.stderr)
        return 1


KERNELS_HELP = (
    "the firmware's float32 kernels: native (navk, firmware/native, built for the runtime on "
    "demand; default) or python (no navk: the firmware's Python kernels)"
)


def add_kernels_option(parser):
    """--kernels native|python (default native), for the commands that run the firmware."""
    parser.add_argument(
        "--kernels", default="native", choices=("native", "python"), help=KERNELS_HELP
    )


BOARD_HELP = (
    "the image the f411 runtime runs: WEACT_F411_BLACKPILL (default) or NUCLEO_F411RE; built "
    "(or brought up to date) first, as `make image BOARD=...` builds it"
)


def add_board_option(parser):
    """--board NAME, the image of the f411 runtime (the emulated STM32F411)."""
    from host_emulator.f411 import boards

    parser.add_argument("--board", default=None, choices=tuple(boards.BOARDS), help=BOARD_HELP)


def check_board(runtime, board):
    """UsageError for --board with a runtime that runs no image."""
    from host_emulator import runtimes

    if board is not None and runtimes.get(runtime).name not in runtimes.BOARD_RUNTIMES:
        which = " or ".join(runtimes.BOARD_RUNTIMES)
        raise UsageError(f"--board is for --runtime {which} (the emulated STM32F411 runs a "
                         f"board's image); {runtime} runs none")  # fmt: skip


def _jobs(text):
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number, at least 1: {text!r}")
    return n


def add_jobs_option(parser, what="parallel runs"):
    """--jobs N (at least 1; default 2), for the benchmarks that run in a process pool."""
    parser.add_argument("--jobs", type=_jobs, default=2, help=f"{what} (default 2)")


def number(text, name):
    """float(text), or a UsageError naming the option."""
    try:
        return float(text)
    except (TypeError, ValueError):
        raise UsageError(f"{name} must be a number, got {text!r}") from None


def positive(text, name):
    v = number(text, name)
    if not v > 0:
        raise UsageError(f"{name} must be positive, got {text!r}")
    return v


def check_scenario(name):
    from host_emulator.sim import trajectory

    if name not in trajectory.SCENARIOS:
        known = ", ".join(sorted(trajectory.SCENARIOS))
        raise EmulatorError(f"unknown scenario {name!r}; known scenarios: {known}")


def check_duration(duration_s):
    if duration_s is not None and not (1.0 <= duration_s <= MAX_DURATION_S):
        raise EmulatorError(f"--duration must be 1 to {MAX_DURATION_S:g} s")


def check_seed(seed):
    if seed < 0:
        raise EmulatorError("--seed must be 0 or more")
