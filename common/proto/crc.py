"""The CRC-32 of every CRC-protected thing the board and the host exchange (extended frames,
raw-input records, stimulus and session files, the files tools.flash deploys).

It is zlib's CRC-32, which the board computes with `binascii.crc32`: the host uses the same
function, so there is one definition. tests/proto/test_formats.py checks it against crcmod's
"crc-32", an independent implementation of the same polynomial.
"""

import binascii


def crc32(data, value=0):
    """CRC-32 of data (continuing from value) as an unsigned 32-bit int."""
    return binascii.crc32(data, value) & 0xFFFFFFFF
