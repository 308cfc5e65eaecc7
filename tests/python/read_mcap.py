#!/usr/bin/env python3
"""Independent reader of the rigmon MCAP layout (uses the `mcap` package, not rigmon).

Usage: read_mcap.py FILE.mcap [--full]

Decodes every message from the layout documented in the README (topics /accel/<name>,
/tacho/analog, /tacho/edges; schemas rigmon.SampleBlock, rigmon.TachoEdges; message encoding
rigmon-le, little-endian) and prints one JSON object:
  {"profile", "metadata": {name: {k: v}}, "schemas": {name: encoding},
   "channels": {topic: {"n", "first_sample", "sample_rate_hz", "unit", "sum", "sum_sq",
                        "samples_bits" (with --full: f32 bit patterns)}},
   "edges": [...], "edges_bits": [f64 bit patterns]}
Sample blocks are checked for contiguity (first_sample of each block == samples so far) and
for t0_s == first_sample / sample_rate_hz.
"""
import json
import math
import struct
import sys

from mcap.reader import make_reader


def decode_sample_block(data):
    first_sample, t0_s, fs, n, unit_len = struct.unpack_from("<QddIH", data, 0)
    off = 30
    unit = data[off:off + unit_len].decode("utf-8")
    off += unit_len
    if len(data) != off + 4 * n:
        raise ValueError(f"SampleBlock length {len(data)} != {off + 4 * n}")
    samples = struct.unpack_from(f"<{n}f", data, off)
    bits = struct.unpack_from(f"<{n}I", data, off)
    return first_sample, t0_s, fs, unit, samples, bits


def decode_edges(data):
    first_sample, fs, n = struct.unpack_from("<QdI", data, 0)
    if len(data) != 20 + 8 * n:
        raise ValueError(f"TachoEdges length {len(data)} != {20 + 8 * n}")
    return first_sample, fs, list(struct.unpack_from(f"<{n}d", data, 20)), list(struct.unpack_from(f"<{n}Q", data, 20))


def main():
    path = sys.argv[1]
    full = "--full" in sys.argv[2:]
    out = {"metadata": {}, "schemas": {}, "channels": {}, "edges": [], "edges_bits": []}
    with open(path, "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        out["profile"] = header.profile
        for m in reader.iter_metadata():
            out["metadata"][m.name] = dict(m.metadata)
        blocks = {}
        for schema, channel, message in reader.iter_messages():
            out["schemas"][schema.name] = schema.encoding
            if channel.message_encoding != "rigmon-le":
                raise ValueError(f"{channel.topic}: message encoding {channel.message_encoding}")
            if schema.name == "rigmon.SampleBlock":
                first, t0, fs, unit, samples, bits = decode_sample_block(message.data)
                if abs(t0 - first / fs) > 1e-9 * max(1.0, t0):
                    raise ValueError(f"{channel.topic}: t0_s {t0} != {first}/{fs}")
                blocks.setdefault(channel.topic, []).append((first, fs, unit, samples, bits))
            elif schema.name == "rigmon.TachoEdges":
                _, _, times, tbits = decode_edges(message.data)
                out["edges"].extend(times)
                out["edges_bits"].extend(tbits)
            else:
                raise ValueError(f"unknown schema {schema.name}")
    for topic, bl in blocks.items():
        bl.sort(key=lambda b: b[0])
        samples = []
        bits = []
        for first, fs, unit, s, b in bl:
            if first != len(samples):
                raise ValueError(f"{topic}: block at {first} but {len(samples)} samples so far")
            samples.extend(s)
            bits.extend(b)
        ch = {
            "n": len(samples),
            "first_sample": bl[0][0],
            "sample_rate_hz": bl[0][1],
            "unit": bl[0][2],
            "sum": math.fsum(samples),
            "sum_sq": math.fsum(x * x for x in samples),
        }
        if full:
            # Exact values: IEEE-754 bit patterns (JSON decimals may lose the last bit).
            ch["samples_bits"] = list(bits)
        out["channels"][topic] = ch
    order = sorted(range(len(out["edges"])), key=lambda k: out["edges"][k])
    out["edges"] = [out["edges"][k] for k in order]
    out["edges_bits"] = [out["edges_bits"][k] for k in order]
    json.dump(out, sys.stdout)
    print()


if __name__ == "__main__":
    main()
