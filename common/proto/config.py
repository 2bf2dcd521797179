"""The board's configuration file (`/flash/ins.cfg`) on the host: firmware/lib/config.py's
binary encoding is the one codec, imported from the firmware itself, so the host reads and
writes exactly what the board does.

Values travel as a dict of `BoardConfig` attribute names (JSON-able: floats are the exact
values of the board's float32s, so re-encoding gives the same bits). `values_of` and
`from_values` convert between that dict and the firmware's object; `to_bytes` / `decode` are
the file; `load` reads a file given by a user (the binary file, or a JSON object of settings).
A stimulus carries its run's values in its header (`run_values` adds a run's overrides).
Imported as `board_config` (the firmware's own module is `config`).
"""

import json
import struct
from pathlib import Path

import numpy as np

from common import firmware_env
from common.errors import EmulatorError


class ConfigError(EmulatorError):
    """A configuration that cannot be read or that the firmware would not accept."""


def _firmware_config():
    firmware_env.install()
    import config

    return config


def parse_setting(text):
    """(name, value) of one `NAME=VALUE` board setting as `config set` and `replay --set`
    take it: an int setting in Python's integer syntax (0x.. too), a float setting as n
    comma-separated numbers (a float for n = 1, a list otherwise), a calibration matrix also
    as `identity`. ConfigError (one sentence) for a malformed one; the values' ranges are the
    firmware's to check (`from_values`, BoardConfig.validate)."""
    config = _firmware_config()
    if "=" not in text:
        raise ConfigError(f"expected NAME=VALUE, got {text!r}.")
    name, value = (s.strip() for s in text.split("=", 1))
    schema = {row[1]: row for row in config._SCHEMA}
    if name not in schema:
        raise ConfigError(f"unknown setting {name!r}; the settings are: {', '.join(schema)}.")
    _rid, _name, kind, n, _default = schema[name]
    try:
        if kind == config._INT:
            return name, int(value, 0)
        if name.endswith("_matrix") and value.lower() in ("identity", "none", ""):
            return name, None
        values = [float(x) for x in value.split(",")]
    except ValueError:
        what = "an integer" if kind == config._INT else f"{n} comma-separated number(s)"
        raise ConfigError(f"{name} must be {what}, got {value!r}.") from None
    if len(values) != n:
        raise ConfigError(f"{name} takes {n} comma-separated numbers, got {len(values)}.")
    return name, values[0] if n == 1 else values


def format_setting(value, digits=9):
    """A setting's value as text, the inverse of parse_setting: `identity` for a calibration
    matrix that is None, numbers comma-separated, floats to `digits` significant digits (9
    give a float32 back exactly)."""
    if value is None:
        return "identity"
    if isinstance(value, list):
        return ",".join(f"{x:.{digits}g}" for x in value)
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def default_output_baud():
    """The RS485 baud rate of a board without a configuration file."""
    return _firmware_config().BoardConfig().output_baud


def written(cfg):
    """(data, back, problem): the file the board would hold for a BoardConfig, the BoardConfig
    the board reads back from it, and the firmware's verdict (BoardConfig.validate) on *that*
    one, as config.load gives it on the board: None if it loads, else the message. Every host
    check of a configuration goes through here, so that what passes on the host is what the
    board loads: the file holds float32s, and a Python double typed on the host is not the
    float32 the board reads. (data, back) are None when cfg cannot be written at all: the
    verdict on cfg's own values comes first (it names the bad value; the file cannot hold an
    int beyond int32, a float beyond float32's range)."""
    config = _firmware_config()
    problem = cfg.validate()
    if problem:
        return None, None, problem
    try:
        data = config.encode(cfg)
    except (struct.error, OverflowError, TypeError) as e:
        return None, None, f"a value the file cannot hold ({e})"
    back = config.decode(data)
    return data, back, back.validate()


def from_values(values):
    """The firmware BoardConfig the board loads from a file with these values (the rest at
    their defaults): its floats are the file's float32s (`written`); ConfigError for a name or
    value the firmware does not accept."""
    config = _firmware_config()
    cfg = config.BoardConfig()
    for name in values:
        if not hasattr(cfg, name):
            raise ConfigError(f"unknown board configuration setting {name!r}")
    cfg.apply([(k, list(v) if isinstance(v, (list, tuple)) else v) for k, v in values.items()])
    _data, back, problem = written(cfg)
    if problem:
        raise ConfigError(f"board configuration rejected by the firmware: {problem}")
    return back


def catalogue():
    """(name, default, allowed) texts of every ins.cfg setting in the file's order: what
    `replay --set help` and `config set help` print (allowed: the firmware's own ranges, where
    it has a table of them)."""
    config = _firmware_config()

    ranges = {
        name: f"{config._dec(lo, den)}..{config._dec(hi, den)}" + (f" {unit}" if unit else "")
        + (", above 0" if open_low else "")
        for name, lo, hi, den, unit, open_low in config._RANGES
    }  # fmt: skip
    ranges["profile"] = "0 car, 1 handheld"
    ranges["gyro_range_dps"] = "one of " + ", ".join(map(str, config._GYRO_RANGES))
    ranges["accel_range_g"] = "one of " + ", ".join(map(str, config._ACCEL_RANGES))
    for name in ("output_baud", "gnss_baud"):
        ranges[name] = "one of " + ", ".join(map(str, config._BAUDS))
    ranges["display"] = "0 off, 1 the status page on the UsartGPU screen"
    ranges["display_baud"] = "one of " + ", ".join(str(b) for b in config._BAUDS if b >= 38400)
    ranges["display_w"], ranges["display_h"] = "220..480 px", "176..320 px"
    for name in ("display_fg", "display_bg", "display_warn", "display_fault"):
        ranges[name] = "0..255, a palette index"
    base = values_of(from_values({}))
    return [
        (row[1], format_setting(base[row[1]], 6), ranges.get(row[1], "")) for row in config._SCHEMA
    ]


def print_catalogue(option):
    """`OPTION help`: every ins.cfg setting with its default (and range, for the floats)."""
    print(f"{option} NAME=VALUE, the board settings (firmware/lib/config.py) and their "
          "defaults; the float ranges are what still navigates within the board spec "
          "(docs/benchmarks/settings.md):")  # fmt: skip
    for name, value, limits in catalogue():
        print(f"  {name} = {value}" + (f"   ({limits})" if limits else ""))


def _plain(v):
    if v is None or isinstance(v, (bool, int, str)):
        return v
    if isinstance(v, (float, np.floating)):
        return float(v)
    return [_plain(x) for x in v]


def values_of(cfg):
    """A firmware BoardConfig -> dict of its settings (JSON-able)."""
    return {name: _plain(value) for name, value in vars(cfg).items()}


def to_bytes(values):
    """The configuration file the board would hold for these values."""
    return _firmware_config().encode(from_values(values))


def decode(data):
    """The BoardConfig in a configuration file's bytes, checked as the board checks it on load
    (config.load); ConfigError "corrupt (why)" or "invalid: why" otherwise."""
    config = _firmware_config()
    try:
        cfg = config.decode(data)
    except (ValueError, IndexError) as e:
        raise ConfigError(f"corrupt ({e})") from None
    problem = cfg.validate()
    if problem:
        raise ConfigError(f"invalid: {problem}")
    return cfg


# The board's file is 386 bytes with this schema (6-byte header, 40 records, CRC-32:
# firmware/lib/config.py `encode`); a JSON file of settings is about 1 KB. The bound only keeps
# /dev/zero or a capture given by mistake out of memory.
MAX_FILE_BYTES = 64 * 1024


def read_file(path):
    """A configuration file's bytes, at most MAX_FILE_BYTES; ConfigError naming the file (one
    that cannot be read, or one far larger than any configuration) otherwise."""
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)
    except OSError as e:
        raise ConfigError(f"cannot read configuration {path}: {e.strerror}") from None
    if len(data) > MAX_FILE_BYTES:
        raise ConfigError(
            f"{path} is not a configuration file: it holds more than {MAX_FILE_BYTES // 1024} KB "
            "(the board's is under 1 KB)"
        )
    return data


def load(path):
    """The configuration values in a user's file: a JSON object of settings (missing ones keep
    their defaults), or else the board's own file (binary, as on its flash)."""
    data = read_file(path)
    if data.lstrip()[:1] != b"{":
        try:
            return values_of(decode(data))
        except ConfigError as e:
            raise ConfigError(
                f"configuration {path} is {e}: give the board's configuration file or a JSON "
                "object of settings"
            ) from None
    try:
        values = json.loads(data.decode())
        if not isinstance(values, dict):
            raise ValueError("not a JSON object")
    except (UnicodeDecodeError, ValueError) as e:
        raise ConfigError(f"configuration {path} is not a JSON object of settings ({e})") from None
    try:
        return values_of(from_values(values))
    except ConfigError as e:
        raise ConfigError(f"configuration {path}: {e}") from None


def run_values(stim, overrides=None):
    """The configuration values of a run: the stimulus header's "config", then the overrides
    (everything else keeps firmware/lib/config.py's defaults)."""
    values = stim.config
    values.update(overrides or {})
    return values


def write_flash(workdir, values):
    """An emulated board's flash: workdir/flash/ins.cfg holding `values`; returns its path."""
    flash = Path(workdir) / "flash"
    flash.mkdir(parents=True, exist_ok=True)
    path = flash / "ins.cfg"
    path.write_bytes(to_bytes(values))
    return path
