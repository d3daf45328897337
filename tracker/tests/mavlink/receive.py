"""An independent MAVLink receiver for tracker/tests/mavlink_cli.rs (pymavlink, common dialect,
MAVLink 2): binds a UDP port on 127.0.0.1, prints `port N` once it listens, then collects
every message until none has arrived for IDLE_S seconds (or DEADLINE_S passed) and prints them
as one JSON list. NaN fields print as null (JSON has no NaN)."""
import json
import math
import os
import sys
import time

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402

IDLE_S = 3.0
DEADLINE_S = 120.0


def plain(v):
    if isinstance(v, float) and math.isnan(v):
        return None
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    return v


def main():
    conn = mavutil.mavlink_connection("udpin:127.0.0.1:0", dialect="common")
    print("port", conn.port.getsockname()[1], flush=True)
    out = []
    start = time.monotonic()
    last = None
    while time.monotonic() - start < DEADLINE_S:
        m = conn.recv_match(blocking=True, timeout=0.2)
        if m is None:
            if last is not None and time.monotonic() - last > IDLE_S:
                break
            continue
        last = time.monotonic()
        if m.get_type() == "BAD_DATA":
            out.append({"type": "BAD_DATA"})
            continue
        d = {k: plain(v) for k, v in m.to_dict().items()}
        d["_version2"] = m.get_msgbuf()[0] == 0xFD
        d["_sysid"] = m.get_srcSystem()
        d["_compid"] = m.get_srcComponent()
        out.append(d)
    json.dump(out, sys.stdout)
    sys.stdout.write("\n")


main()
