"""Replay of recorded drives (real data) through the firmware: datasets, exchange formats,
conversion to a stimulus, evaluation against the recording's reference."""
