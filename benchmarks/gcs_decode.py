"""Decoding a PI data recorder's reply (``DRR?``): line by line against byte by byte.

The hexapod's recorded motion comes back as one GCS reply of text rows (6 columns at the
recorder's rate); a quick calibration reads about 12 MB of them. Prints the throughput of
``GcsReplyDecoder`` (clean text goes line by line) and of the byte-wise decoder it falls
back to, on the same reply in the same 4 kB reads, and their ratio.
Usage: ``python benchmarks/gcs_decode.py [MEGABYTES]`` (below 1, the decoder's limit).
"""

from __future__ import annotations

import sys
import time

from drivers.codecs import gcs


def reply(megabytes: float) -> bytes:
    row = "12.345678 -0.001234 0.000567 1.234567 -2.345678 0.123456 \n"
    rows = row * max(1, int(megabytes * 1e6 / len(row)))
    return ("# REC_RATE = 1000 \n# END_HEADER \n" + rows[:-2] + "\n").encode()


def throughput(data: bytes, feed) -> float:
    start = time.perf_counter()
    out = []
    for i in range(0, len(data), 4096):  # the socket's reads
        out += feed(data[i:i + 4096])
    seconds = time.perf_counter() - start
    assert len(out) == 1
    return len(data) / seconds / 1e6


def main(argv: list[str]) -> int:
    data = reply(float(argv[0]) if argv else 0.9)  # a reply over 1 MB is refused (max_bytes)
    lines = throughput(data, gcs.GcsReplyDecoder().feed_located)
    slow = gcs.GcsReplyDecoder()
    bytewise = throughput(data, lambda chunk: gcs._TextDecoder.feed_located(slow, chunk))
    print(f"DRR? reply of {len(data) / 1e6:.1f} MB in 4 kB reads")
    print(f"  line by line: {lines:8.1f} MB/s")
    print(f"  byte by byte: {bytewise:8.1f} MB/s")
    print(f"  ratio:        {lines / bytewise:8.0f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
