"""An encoder log of an hour at 1 kHz, as `t,theta` (s, rad), to time
`koopman import` on: a 0.8 m string released at 0.5 rad, Q about 2000
(decaying to 0.08 rad by the end), an offset of 0.03 rad and the
encoder's rounding (4096 counts a turn). About 65 MB.

    python3 docs/import/hour_at_1khz.py /tmp/hour.csv
    /usr/bin/time -f "%e s %M KB" target/release/koopman import /tmp/hour.csv --dt 0.04 --out /tmp/hour-out.csv
"""
import math
import sys

L, G, THETA0, OFFSET, Q = 0.8, 9.81, 0.5, 0.03, 2000.0
COUNT = 2 * math.pi / 4096
RATE, SECONDS = 1000, 3600

w0 = math.sqrt(G / L)
gamma = w0 / (2 * Q)
with open(sys.argv[1], "w") as f:
    f.write("t,theta\n")
    lines = []
    for k in range(RATE * SECONDS):
        t = k / RATE
        a = THETA0 * math.exp(-gamma * t)
        # The amplitude's period lengthening, to first order in a^2.
        w = w0 * (1 - a * a / 16)
        theta = OFFSET + a * math.cos(w * t)
        lines.append(f"{t:.3f},{round(theta / COUNT) * COUNT:.5f}\n")
        if len(lines) == 100_000:
            f.writelines(lines)
            lines = []
    f.writelines(lines)
