# Two commands on a fresh machine (Python 3.11): `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test lint accuracy bench-nav accuracy-report replay clean

$(STAMP): requirements.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -r requirements.txt
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m host_emulator demo

test: $(STAMP)
	$(BIN)/python -m pytest -q

lint: $(STAMP)
	$(BIN)/ruff check .

# Accuracy of the float32 math functions over their domains, and of the rotation and lat/lon
# kernels (minutes; the figures of docs/float32.md).
accuracy: $(STAMP)
	$(BIN)/python -m host_emulator.reference.accuracy
	$(BIN)/python -m host_emulator.reference.core_figures

# Navigation accuracy and per-tick cost on simulated data (a few minutes; docs/benchmarks/).
bench-nav: $(STAMP)
	$(BIN)/python -m host_emulator.bench_nav

# Navigation accuracy on the real drive_0708 and the simulated scenarios (~3 min; writes
# docs/accuracy.md and docs/benchmarks/accuracy.json).
accuracy-report: $(STAMP)
	$(BIN)/python -m host_emulator.replay.accuracy_report

# The real drive through the firmware with report and plots (out/replay/).
replay: $(STAMP)
	$(BIN)/python -m host_emulator replay --dataset drive_0708 --out out/replay

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
