#!/usr/bin/env python3
"""Independent reader of a rigmon recording that may be cut short (kill -9, disk full).

Usage: read_cut_mcap.py FILE.mcap

Uses the `mcap` package's linear stream reader (not rigmon): reads records from the start,
decompresses each chunk and checks its CRC, and stops at the first record that is incomplete
or damaged; nothing from an incomplete chunk is used. Prints one JSON object:
  {"bytes": file size, "bytes_used": end of the last complete record,
   "complete_chunks", "footer": bool, "stopped": why reading stopped or null,
   "seconds": {topic: seconds of samples in /accel and /tacho blocks},
   "messages": {topic: count}, "contiguous": bool (every SampleBlock starts where the
   previous one of its topic ended)}
"""
import json
import struct
import sys

from mcap.records import Channel, Footer, Message, Schema
from mcap.stream_reader import StreamReader


def complete_records(f, size):
    """End offset of the last record whose whole length is in the file, and the number of
    complete Chunk records (a plain scan of opcode + length prefixes)."""
    f.seek(8)
    at, chunks = 8, 0
    while at + 9 <= size:
        op, n = struct.unpack("<BQ", f.read(9))
        if at + 9 + n > size:
            break
        at += 9 + n
        chunks += op == 0x06
        f.seek(at)
    return at, chunks


def main(path):
    with open(path, "rb") as f:
        size = f.seek(0, 2)
        used, chunks = complete_records(f, size)
        f.seek(0)
        # The mcap package's stream reader decompresses each chunk whole and checks its CRC
        # before yielding any record from it; it raises at the first incomplete record.
        reader = StreamReader(f, skip_magic=False, validate_crcs=True)
        schemas, channels = {}, {}
        samples, rates, messages, next_first = {}, {}, {}, {}
        contiguous, footer, stopped = True, False, None
        try:
            for r in reader.records:
                if isinstance(r, Schema):
                    schemas[r.id] = r.name
                elif isinstance(r, Channel):
                    channels[r.id] = r
                elif isinstance(r, Footer):
                    footer = True
                elif isinstance(r, Message):
                    ch = channels[r.channel_id]
                    messages[ch.topic] = messages.get(ch.topic, 0) + 1
                    if schemas.get(ch.schema_id) == "rigmon.SampleBlock":
                        first, _t0, fs, n = struct.unpack_from("<QddI", r.data, 0)
                        if len(r.data) < 30 + 4 * n:
                            raise ValueError(f"{ch.topic}: SampleBlock shorter than its n")
                        if next_first.get(ch.topic, first) != first:
                            contiguous = False
                        next_first[ch.topic] = first + n
                        samples[ch.topic] = samples.get(ch.topic, 0) + n
                        rates[ch.topic] = fs
        except Exception as e:  # cut short or damaged: stop here
            stopped = f"{type(e).__name__}: {e}"
    print(json.dumps({
        "bytes": size,
        "bytes_used": used,
        "complete_chunks": chunks,
        "footer": footer,
        "stopped": stopped,
        "seconds": {t: samples[t] / rates[t] for t in samples},
        "messages": messages,
        "contiguous": contiguous,
    }))


if __name__ == "__main__":
    main(sys.argv[1])
