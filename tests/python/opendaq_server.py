#!/usr/bin/env python3
"""The openDAQ SDK's reference device behind its LT streaming server, for rigmon's tests.

A real counterpart nobody here wrote: `opendaq.Instance()` with the reference device
(`daqref://device0`), configured from the command line, served by the SDK's
"OpenDAQLTStreaming" server. No discovery (mDNS) server is added. The SDK binds its ports on
every interface and has no option to choose one, so the tests run this script inside their
own network namespace (`unshare -n`, only `lo` up).

Usage: opendaq_server.py [--ws-port 7414] [--control-port 7438] [--rate HZ] [--channels N]
                         [--wave CH:KIND:FREQ:AMP ...] [--seconds S]
  KIND is Sine, Rect, None, Counter or Constant (the reference channel's `Waveform`).
Prints one line `READY {json}` (ports, rate, signal ids) once the server listens, then runs
until stdin closes (the parent went away) or --seconds pass.
"""
import argparse
import json
import sys
import threading
import time

import opendaq

WAVES = ["Sine", "Rect", "None", "Counter", "Constant"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ws-port", type=int, default=7414)
    ap.add_argument("--control-port", type=int, default=7438)
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--channels", type=int, default=2)
    ap.add_argument("--wave", action="append", default=[])
    ap.add_argument("--seconds", type=float, default=600.0)
    a = ap.parse_args()

    inst = opendaq.Instance()
    inst.set_root_device("daqref://device0")
    dev = inst.root_device
    dev.set_property_value("NumberOfChannels", a.channels)
    dev.set_property_value("GlobalSampleRate", a.rate)
    for spec in a.wave:
        ch, kind, freq, amp = spec.split(":")
        c = dev.channels[int(ch)]
        c.set_property_value("Waveform", WAVES.index(kind))
        c.set_property_value("Frequency", float(freq))
        c.set_property_value("Amplitude", float(amp))
        c.set_property_value("DC", 0.0)
        c.set_property_value("NoiseAmplitude", 0.0)
    st = opendaq.IServerType.cast_from(inst.available_server_types["OpenDAQLTStreaming"])
    cfg = st.create_default_config()
    cfg.set_property_value("WebsocketStreamingPort", a.ws_port)
    cfg.set_property_value("WebsocketControlPort", a.control_port)
    inst.add_server("OpenDAQLTStreaming", cfg)
    info = {
        "ws_port": a.ws_port,
        "control_port": a.control_port,
        "rate": dev.get_property_value("GlobalSampleRate"),
        "channels": len(dev.channels),
        "signals": [s.global_id for s in dev.signals_recursive],
        "sdk": opendaq.__version__,
    }
    print("READY " + json.dumps(info), flush=True)

    done = threading.Event()

    def watch_stdin():
        try:
            while sys.stdin.read(4096):
                pass
        finally:
            done.set()

    threading.Thread(target=watch_stdin, daemon=True).start()
    done.wait(a.seconds)


if __name__ == "__main__":
    main()
