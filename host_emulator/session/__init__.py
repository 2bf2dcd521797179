"""Board sessions: record a board's output stream, rebuild its input from the raw-input records
and replay it through the emulator; the replayed output must equal the recorded one.

    python -m host_emulator session record /dev/ttyUSB0 --out drive.ins --config ins.cfg
    python -m host_emulator session replay drive.ins [--runtime mpy_unix] [--until-gap]
    python -m host_emulator session report drive.ins [--out DIR]

With the configuration setting `raw_record` = 1 the firmware sends, after the frames of each
5 ms tick, a raw-input record (proto/records.py): the tick's start time, the parser's PPS edge
time, the BMI055 data registers as read, the saturation flag and the GNSS bytes fed to the
parser. Those, the board's configuration file and the same firmware are all the firmware's
output depends on, so the emulator fed with them sends the same bytes; docs/sessions.md says
where a real board's timing (which the emulator does not model) can still make a fix land one
tick apart.

    record.py   capture into a session file (proto/session_file.py)
    walk.py     the recorded stream, tick by tick from the board's first, to the end or a gap
    rebuild.py  the emulator's input (a stimulus) rebuilt from the walked recording
    compare.py  the replayed output against the recorded one (what is compared, and how)
    replay.py   the whole replay: read, walk, rebuild, run, compare
    report.py   report.md and plots of a recording, without truth
    cli.py      the `session` command
"""
