"""The board configuration a replay runs the firmware with, and where each setting came from.

A board loads `/flash/ins.cfg` (firmware/lib/config.py) at start-up. A replay puts its settings
in the stimulus header ("config"); the runtimes write them into the emulated board's ins.cfg
(proto/config.py `write_flash`), so the unmodified firmware loads them as a board does. The
settings, in the order they are applied (a later source overrides an earlier one):

    replay    derived from the data by to_stimulus.convert: gyro_range_dps and accel_range_g
              (the smallest BMI055 ranges that hold the recording), gnss_baud (fits the GNSS
              epochs), lever_b_m (antlever), mount_ypr_deg (installangle), gnss_uere_m and
              gnss_hdop_max (from the GNSS sigmas), gnss_latency_s (epochs sent without PPS)
    dataset   the dataset's own: drive_0708's BOARD_CONFIG, a KF-GINS dataset.yaml's `board:`
    --set     the command line's NAME=VALUE (ReplayOptions.config)

Every other setting keeps the firmware's default. A NAME=VALUE is parsed by the parser
`config set` uses (proto/config.py `parse_setting`) and checked by the firmware's own
validation (BoardConfig.validate), so a replay accepts exactly what a board would load.
"""

from common.errors import EmulatorError
from common.proto import config as board_config

REPLAY, DATASET, COMMAND_LINE = "replay", "dataset", "--set"
DETECTED = "detected"  # chosen from the data (replay/carrier.py: the profile)
# Settings a scored replay cannot change: the score reads every 52-byte frame (one per tick)
# and the extended frames (the origin of the frames' positions).
_SCORED = {
    "output_every_ticks": (1, "the score needs the 52-byte frame of every tick"),
}


def problem(values):
    """None if the firmware accepts these values (the rest at their defaults), else its
    message naming the first bad one."""
    try:
        board_config.from_values(values)
    except board_config.ConfigError as e:
        return str(e).removeprefix("board configuration rejected by the firmware: ")
    return None


def parse(text, where=COMMAND_LINE):
    """(name, value) of one NAME=VALUE, checked against the firmware's ranges on its own;
    EmulatorError "where NAME=VALUE: why" otherwise."""
    try:
        name, value = board_config.parse_setting(text)
    except board_config.ConfigError as e:
        raise EmulatorError(f"{where} {text}: {str(e).rstrip('.')}") from None
    why = problem({name: value})
    if why:
        raise EmulatorError(f"{where} {text}: the firmware refuses it: {why}")
    return name, value


def check_scorable(values, sources):
    """EmulatorError for a setting that would leave the replay nothing to score."""
    for name, (want, why) in _SCORED.items():
        if name in values and values[name] != want:
            raise EmulatorError(
                f"{name}={values[name]} ({sources.get(name, REPLAY)}): a replay runs with "
                f"{name}={want}: {why}"
            )
    if values.get("ext_every_ticks", 1) == 0:
        raise EmulatorError(
            f"ext_every_ticks=0 ({sources.get('ext_every_ticks', REPLAY)}): the score reads "
            "the extended frames (the origin of the positions): give 1 or more"
        )


def defaults():
    """The firmware's default settings as values (proto/config.py `values_of`)."""
    return board_config.values_of(board_config.from_values({}))


def nav_config(values):
    """The navigator configuration (firmware/lib/navcfg.NavConfig, float32 values) the firmware
    builds from these settings: thresholds a diagnosis needs (heading_speed_m_s, ...)."""
    return board_config.from_values(values).nav_config()


def _text(value):
    return board_config.format_setting(value, 6)


def describe(values, sources):
    """'name=value (source), ...' of the settings that differ from the firmware's defaults."""
    base = defaults()
    parts = [
        f"{name}={_text(value)} ({sources.get(name, REPLAY)})"
        for name, value in values.items()
        if base.get(name) != value
    ]
    return ", ".join(parts) or "the firmware's defaults"


def catalogue():
    """(name, default, allowed) texts of every ins.cfg setting: proto/config.py's."""
    return board_config.catalogue()
