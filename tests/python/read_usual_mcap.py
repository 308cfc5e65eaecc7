#!/usr/bin/env python3
"""The usual way to read an MCAP file with the Python `mcap` package (not rigmon):
`make_reader(open(path, "rb")).iter_messages()`, the indexed reader that looks for the
footer and summary first and falls back to a linear read when there is no summary.

Usage: read_usual_mcap.py FILE.mcap

Prints one JSON object: {"messages": {topic: count}, "total": n, "summary": bool (the file has
a summary section), "error": null or what the reader raised (messages counted before it)}.
"""
import json
import sys

from mcap.reader import make_reader


def main(path):
    counts, error, summary = {}, None, False
    try:
        with open(path, "rb") as f:
            reader = make_reader(f)
            summary = reader.get_summary() is not None
            for _schema, channel, _message in reader.iter_messages():
                counts[channel.topic] = counts.get(channel.topic, 0) + 1
    except Exception as e:  # the finding: what the usual reader does with the file
        error = f"{type(e).__name__}: {e}"
    print(json.dumps({
        "messages": counts,
        "total": sum(counts.values()),
        "summary": summary,
        "error": error,
    }))


if __name__ == "__main__":
    main(sys.argv[1])
