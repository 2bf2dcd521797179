"""Decode, watch, record and export what an INS board sends: `python -m tools.monitor`
(docs/monitor.md). stream: incremental decoder on host_emulator/frames.py; source: serial port
or capture file; view: live view and summary; export: CSV and MDF4; cli: the command line."""
