"""Decode, watch, record and export what an INS board sends: `python -m tools.monitor`
(docs/monitor.md). source: serial port or capture file; clock: the board time of each frame;
view: live view and summary; nmea: the receiver's GGA/RMC from the raw-input records; export:
CSV and MDF4 (mdf_meta: the MDF4 header and channel comments); cli: the command line. The
stream decoder and the record layouts are common/proto's, shared with the emulator."""
