# Two commands on a fresh machine (Python 3.11): `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test toolchain native layout lint accuracy bench-nav bench-board figures bench-faults bench-real bench-settings \
	cpi accuracy-report \
	digests replay build-flash deploy console monitor virtual-board image flash-image clean

# pip's own progress shown (no --quiet): the first install takes minutes
$(STAMP): requirements.txt
	@echo "installing the pinned dependencies into $(VENV) (first time: a few minutes)"
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --disable-pip-version-check --progress-bar on -r requirements.txt
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m host_emulator demo

# on every core (pytest-xdist): builds shared by the tests take a lock (common/toolchain locked)
test: $(STAMP) toolchain native
	$(BIN)/python -m pytest -q -n auto

# The Debian cross compiler and QEMU for the image and the emulated Cortex-M4F board: installed
# (pinned) when missing if run as root, else the command to run is printed and make stops.
toolchain:
	@common/toolchain/ensure.sh

# The native float32 kernels (firmware/native), three builds out of tree in build/native/
# (docs/native.md): armv7emsp and x64 MicroPython native modules, the CPython (cffi) extension.
# Seconds; make decides what is stale. A missing compiler stops it with what to install.
native: $(STAMP) toolchain
	$(BIN)/python -m common.native

# firmware/native/layout.h and tuning.h, generated from the firmware's Python constants (never
# edited by hand; tests/native/test_layout.py fails when they are stale)
layout: $(STAMP)
	$(BIN)/python -m common.native.layout

lint: $(STAMP)
	$(BIN)/ruff check .

# Accuracy of the float32 math functions over their domains, and of the rotation and lat/lon
# kernels (minutes; the figures of docs/float32.md).
accuracy: $(STAMP)
	$(BIN)/python -m host_emulator float32

# Navigation accuracy and per-tick cost on simulated data (a few minutes; docs/benchmarks/).
bench-nav: $(STAMP)
	$(BIN)/python -m host_emulator bench-nav

# What a tick costs the board: the app loop on the emulated Cortex-M4F over urban_drive (three
# configurations) and a hand-held walk, and the image itself on the emulated STM32F411 (raw
# records off and on, a 10 Hz receiver, the status page, the walk): ~18 min on two cores;
# writes docs/benchmarks/board.md.
bench-board: $(STAMP) toolchain native
	$(BIN)/python -m host_emulator bench-board

# The board figures README.md and docs/ quote (<!--fig NAME--> markers), rewritten from
# docs/benchmarks/board.json and the images' budgets (builds them if needed; bench-board does
# this too); tests/bench/test_figures.py fails on a stale one.
figures: $(STAMP)
	$(BIN)/python -m host_emulator figures

# The fault matrix: every fault kind of `run --fault` injected into urban_drive, three seeds,
# on CPython (~11 min on two cores; writes docs/benchmarks/faults.md).
bench-faults: $(STAMP) native
	$(BIN)/python -m host_emulator bench-faults

# Every real recording in ../shared/data replayed through the firmware next to its own fixes,
# scored where its reference exists (docs/benchmarks/realdata.md; a few minutes on two cores)
bench-real: $(STAMP)
	$(BIN)/python -m host_emulator bench-real

# Every board setting swept one at a time over urban_drive and walk on CPython: the ranges that
# still navigate within the board spec (~23 min on two busy cores, 16 CPU-min; writes
# docs/benchmarks/settings.md, the source of firmware/lib/config.py's _RANGES).
bench-settings: $(STAMP) native
	$(BIN)/python -m host_emulator bench-settings

# Navigation accuracy on the real drive_0708 and the simulated scenarios (~3 min; writes
# docs/accuracy.md and docs/benchmarks/accuracy.json).
accuracy-report: $(STAMP)
	$(BIN)/python -m host_emulator accuracy-report

# The change indicator: recompute the frame-stream digests of short runs on every runtime and
# compare them with tests/change_indication/ (make test does too); UPDATE=1 rewrites them, on
# purpose, so the diff shows a behaviour change in review.
digests: $(STAMP)
	$(BIN)/python -m host_emulator digests $(if $(UPDATE),--update)

# CPI of MicroPython on an STM32F4: the published NUCLEO-F401RE perf_bench cycles (PR #18069) over
# the instructions the same benchmarks take on the emulated Cortex-M4F (docs/benchmarks/cpi.md,
# cpi.json; about 45 s, 1.5 min the first time, which builds the emulated board with the F401's
# heap).
cpi: $(STAMP) toolchain
	$(BIN)/python -m host_emulator cpi

# The real drive through the firmware with report and plots (out/replay/).
replay: $(STAMP)
	$(BIN)/python -m host_emulator replay --dataset drive_0708 --out out/replay

# Board tools (docs/deploy.md, docs/monitor.md, docs/virtual_board.md). PORT: the board's USB
# serial port (its REPL) for deploy; the RS485 adapter that carries the frames for monitor.
build-flash: $(STAMP) native
	$(BIN)/python -m tools.flash build --out out/flash $(if $(FLASH_KB),--flash-kb $(FLASH_KB))

deploy: $(STAMP) native
	@test -n "$(PORT)" || { echo "usage: make deploy PORT=/dev/ttyACM0 [CONFIG=ins.cfg]" \
		"[SET='raw_record=1 ...'] [FRAMES_PORT=/dev/ttyUSB0]" >&2; exit 2; }
	$(BIN)/python -m tools.flash deploy --port $(PORT) $(if $(CONFIG),--config $(CONFIG)) \
		$(if $(SET),--set $(SET)) $(if $(FRAMES_PORT),--frames-port $(FRAMES_PORT))

console: $(STAMP)
	@test -n "$(PORT)" || { echo "usage: make console PORT=/dev/ttyACM0" >&2; exit 2; }
	$(BIN)/python -m tools.flash console --port $(PORT)

monitor: $(STAMP)
	@test -n "$(PORT)" || { echo "usage: make monitor PORT=/dev/ttyUSB0 [RECORD=run.ins" \
		"BOARD_PORT=/dev/ttyACM0 | CONFIG=ins.cfg] [CSV=run.csv]" >&2; exit 2; }
	$(BIN)/python -m tools.monitor --port $(PORT) $(if $(RECORD),--record $(RECORD)) \
		$(if $(BOARD_PORT),--board-port $(BOARD_PORT)) $(if $(CONFIG),--config $(CONFIG)) \
		$(if $(CSV),--csv $(CSV))

# endless by default: the scenario again and again, the firmware restarting (DURATION=120: once)
virtual-board: $(STAMP)
	$(BIN)/python -m host_emulator virtual-board --fs out/virtual_board $(if $(FROZEN),--frozen) \
		--duration $(or $(DURATION),0)

# The firmware image (docs/image.md): MicroPython v1.28.0 with firmware/ frozen, built out of tree
# in build/image/BOARD (cached), written to out/image/BOARD/ with its budget; BOARD is
# WEACT_F411_BLACKPILL (default) or NUCLEO_F411RE. flash-image writes it to a board in DFU mode.
image: $(STAMP)
	$(BIN)/python -m tools.image build $(if $(BOARD),--board $(BOARD))

flash-image: $(STAMP)
	$(BIN)/python -m tools.flash image $(if $(FILE),--file $(FILE),$(if $(BOARD),--board $(BOARD)))

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
