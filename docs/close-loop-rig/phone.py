"""A phone's gyroscope export, as phyphox writes it ("Gyroscope" experiment,
comma-separated, quoted names, numbers like 9.969000006E-3): the phone is the
bob of a 0.65 m string released at 0.4 rad, damped by viscous loss (0.005 1/s)
and air drag (0.03 1/rad), sampled at 100 Hz (stamps jittered by up to 0.3 ms)
for 120 s; the swing on z tilted 8 degrees into x, every axis biased by 0.01
rad/s, noise 0.005 rad/s (seed 73). The path is the first argument; its truth
is written beside it (the same name, .json)."""
import math, random, sys

random.seed(73)
L, g, vis, drag = 0.65, 9.81, 0.005, 0.03
th, om = 0.4, 0.0
dt, sub = 0.01, 10
h = dt / sub
tilt = math.radians(8)


def acc(th, om):
    return -g / L * math.sin(th) - vis * om - drag * om * abs(om)


rows = ['"Time (s)","Gyroscope x (rad/s)","Gyroscope y (rad/s)","Gyroscope z (rad/s)","Absolute (rad/s)"']
for k in range(int(120 / dt)):
    w = [om * math.sin(tilt) + 0.01 + 0.005 * random.gauss(0, 1),
         -0.01 + 0.005 * random.gauss(0, 1),
         om * math.cos(tilt) + 0.01 + 0.005 * random.gauss(0, 1)]
    a = math.sqrt(sum(v * v for v in w))
    rows.append(",".join(f"{v:.9E}" for v in [k * dt + 0.0003 * random.random()] + w + [a]))
    for _ in range(sub):  # RK4
        k1 = (om, acc(th, om))
        k2 = (om + h / 2 * k1[1], acc(th + h / 2 * k1[0], om + h / 2 * k1[1]))
        k3 = (om + h / 2 * k2[1], acc(th + h / 2 * k2[0], om + h / 2 * k2[1]))
        k4 = (om + h * k3[1], acc(th + h * k3[0], om + h * k3[1]))
        th += h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        om += h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
open(sys.argv[1], 'w').write("\n".join(rows) + "\n")
# Its truth, as `koopman generate --lab` writes a case's (collect.py reads it).
import json, os
json.dump([{"case": "viscous+drag", "file": os.path.basename(sys.argv[1]), "length": L, "rig": "simple",
            "effects": [["viscous", vis], ["drag", drag]], "rate": 100.0, "theta0": 0.4}],
          open(os.path.splitext(sys.argv[1])[0] + '.json', 'w'), indent=1)
