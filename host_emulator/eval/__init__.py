"""What a firmware run is worth: its output decoded and scored against truth (evaluate.py),
report.md and plots (report.py), two output streams compared record by record (compare.py;
parity.py uses it for the firmware against the model), and the commands that put a run
together: `run` (scenario_run.py), `demo` (demo.py), `gnss-dump` (gnss_dump.py); what a tick
costs the board, from an m4f run's instruction counts (board_cost.py) and an f411 run's
clock (board_time.py)."""
