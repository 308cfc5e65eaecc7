#!/usr/bin/env python3
"""An independent Zenoh client (eclipse-zenoh, Python) for rigmon health messages.

Subscribes to a key expression over an explicit loopback endpoint (multicast scouting off),
validates every message against the rigmon.health v1 schema (required fields and types), and
prints one JSON summary line at the end:
  {"count": N, "states": {...}, "window_states": {...}, "final_state": ..., "keys": [...]}

Usage: zenoh_sub.py (--connect | --listen) tcp/127.0.0.1:PORT [--key rigmon/**/health] [--count N]
                    [--timeout S] [--ready-file PATH]
Exit status: 0 when --count messages arrived, 1 on timeout or an invalid message.
"""
import argparse
import json
import os
import sys
import threading
import time

import zenoh

REQUIRED = {
    "schema": str,
    "schema_version": int,
    "rig": str,
    "asset": str,
    "point": str,
    "seq": int,
    "window": dict,
    "publish_time_ns": int,
    "speed_source": str,
    "quality": dict,
    "probabilities": dict,
    "window_state": str,
    "state": str,
    "confidence": (int, float),
    "novelty": (int, float),
    "fault_bands": dict,
    "model": dict,
    "software_version": str,
}


def validate(msg):
    for key, typ in REQUIRED.items():
        if key not in msg:
            return f"missing field {key!r}"
        if not isinstance(msg[key], typ):
            return f"field {key!r} has type {type(msg[key]).__name__}"
    if msg["schema"] != "rigmon.health" or msg["schema_version"] != 1:
        return f"unexpected schema {msg['schema']} v{msg['schema_version']}"
    w = msg["window"]
    if not (w["end_s"] > w["start_s"]):
        return "window end is not after its start"
    probs = msg["probabilities"]
    if probs and abs(sum(probs.values()) - 1.0) > 1e-3:
        return f"probabilities sum to {sum(probs.values())}"
    if "ok" not in msg["quality"] or "flags" not in msg["quality"]:
        return "quality lacks ok/flags"
    return None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--connect", help="endpoint to connect to, e.g. tcp/127.0.0.1:7448")
    ap.add_argument("--listen", help="endpoint to listen on instead (the daemon connects)")
    ap.add_argument("--key", default="rigmon/**/health")
    ap.add_argument("--count", type=int, default=10)
    ap.add_argument("--timeout", type=float, default=30.0)
    ap.add_argument("--ready-file", help="touch this file once subscribed")
    args = ap.parse_args()

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    if not (args.connect or args.listen):
        ap.error("give --connect or --listen")
    conf.insert_json5("connect/endpoints", json.dumps([args.connect] if args.connect else []))
    conf.insert_json5("listen/endpoints", json.dumps([args.listen] if args.listen else []))
    conf.insert_json5("scouting/multicast/enabled", "false")

    lock = threading.Lock()
    done = threading.Event()
    got = []
    errors = []

    def on_sample(sample):
        try:
            msg = json.loads(sample.payload.to_bytes())
        except Exception as e:  # noqa: BLE001
            errors.append(f"not JSON: {e}")
            done.set()
            return
        err = validate(msg)
        with lock:
            if err:
                errors.append(err)
                done.set()
                return
            got.append((str(sample.key_expr), msg))
            if len(got) >= args.count:
                done.set()

    with zenoh.open(conf) as session:
        sub = session.declare_subscriber(args.key, on_sample)
        if args.ready_file:
            with open(args.ready_file, "w") as f:
                f.write("ready\n")
        deadline = time.time() + args.timeout
        while not done.is_set() and time.time() < deadline:
            done.wait(0.1)
        sub.undeclare()

    states, window_states = {}, {}
    for _, m in got:
        states[m["state"]] = states.get(m["state"], 0) + 1
        window_states[m["window_state"]] = window_states.get(m["window_state"], 0) + 1
    summary = {
        "count": len(got),
        "states": states,
        "window_states": window_states,
        "final_state": got[-1][1]["state"] if got else None,
        "keys": sorted({k for k, _ in got}),
        "errors": errors,
    }
    print(json.dumps(summary))
    sys.stdout.flush()
    ok = not errors and len(got) >= args.count
    os._exit(0 if ok else 1)


if __name__ == "__main__":
    main()
