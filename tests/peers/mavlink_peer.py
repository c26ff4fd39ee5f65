"""An ArduPilot-like boat (and a second vehicle) as MAVLink, made with
pymavlink: writes the messages to a telemetry log (.tlog: an 8-byte
big-endian microsecond time stamp before each frame) and sends the same
frames over UDP, as a telemetry link would.

Used by crates/twin-bridge/tests/peer_pymavlink.rs:

    python3 tests/peers/mavlink_peer.py --tlog OUT.tlog --udp 127.0.0.1:PORT

The boat (system 1) runs 5 s at 10 Hz: SYSTEM_TIME once a second (first),
GPS_RAW_INT (Unix time_usec, 3D fix), ATTITUDE, SERVO_OUTPUT_RAW (left
throttle on output 1, right on output 3) and ESC_TELEMETRY_1_TO_4. A second
vehicle (system 2) sends its own GPS_RAW_INT on the same link.
"""

import argparse
import math
import struct
import time

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

T0 = 1785731240.0  # 2026-08-03T04:27:20Z, the boat's GNSS time at start
BOOT_S = 100.0  # the boat's autopilot booted 100 s before T0


def frames():
    """(arrival time, frame bytes) of the whole run, in order."""
    boat = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    other = mavlink.MAVLink(None, srcSystem=2, srcComponent=1)
    out = []
    for k in range(50):
        t = T0 + 0.1 * k
        boot_ms = int(round((BOOT_S + 0.1 * k) * 1000))
        arrival = t + 0.05
        angle = 0.01 * k
        lat = int(round((59.9 + 20.0 * math.sin(angle) / 111320.0) * 1e7))
        lon = int(round((10.7 + 20.0 * (1 - math.cos(angle)) / 55800.0) * 1e7))
        msgs = []
        if k % 10 == 0:
            msgs.append((boat, boat.system_time_encode(int(round(t * 1e6)), boot_ms)))
        msgs.append((boat, boat.gps_raw_int_encode(
            int(round(t * 1e6)), mavlink.GPS_FIX_TYPE_3D_FIX, lat, lon, 40000,
            80, 120, 200, int(round(math.degrees(angle) * 100)) % 36000, 14)))
        msgs.append((boat, boat.attitude_encode(boot_ms + 20, 0.01, -0.02, angle, 0.0, 0.0, 0.1)))
        msgs.append((boat, boat.servo_output_raw_encode(
            (boot_ms + 30) * 1000, 0, 1700, 1500, 1400, 1500, 0, 0, 0, 0)))
        msgs.append((boat, boat.esc_telemetry_1_to_4_encode(
            [30, 30, 30, 30], [1600, 0, 1600, 0], [100, 0, 100, 0], [5, 0, 5, 0],
            [1200, 0, 900, 0], [k, 0, k, 0])))
        msgs.append((other, other.gps_raw_int_encode(
            int(round(t * 1e6)), mavlink.GPS_FIX_TYPE_3D_FIX, 600000000, 110000000, 0,
            80, 120, 100, 0, 10)))
        for sender, msg in msgs:
            out.append((arrival, bytes(msg.pack(sender))))
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--tlog", required=True)
    parser.add_argument("--udp", required=True, help="HOST:PORT of the bridge")
    args = parser.parse_args()
    run = frames()
    with open(args.tlog, "wb") as tlog:
        for arrival, frame in run:
            tlog.write(struct.pack(">Q", int(round(arrival * 1e6))) + frame)
    link = mavutil.mavlink_connection("udpout:" + args.udp, source_system=1)
    for _, frame in run:
        link.write(frame)
        time.sleep(0.001)
    link.close()


if __name__ == "__main__":
    main()
