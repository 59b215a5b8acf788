"""In-distribution protocol rollouts, as the protocol draws its training
ones (../shared/PROTOCOL.md): the rod's ODE by RK4 at dt / 10, dt = 0.05,
128 observations, L uniform in [2, 5], theta_0 uniform in [pi/2, 0.9 pi],
theta_dot_0 = 0. Writes the project CSV and prints the lengths.

    python3 docs/protocol-check/draw.py SEED N OUT.csv > OUT.truth
    python3 docs/protocol-check/score.py OUT.csv OUT.truth [--steps 64]
"""
import math, random, sys
seed = int(sys.argv[1]); n = int(sys.argv[2]); out = sys.argv[3]
rng = random.Random(seed)
g, dt = 9.81, 0.05
def f(L, s):
    th, w = s
    return (w, -(3 * g / (2 * L)) * math.sin(th))
def rk4(L, s, h):
    k1 = f(L, s); k2 = f(L, (s[0] + h/2*k1[0], s[1] + h/2*k1[1]))
    k3 = f(L, (s[0] + h/2*k2[0], s[1] + h/2*k2[1])); k4 = f(L, (s[0] + h*k3[0], s[1] + h*k3[1]))
    return (s[0] + h/6*(k1[0]+2*k2[0]+2*k3[0]+k4[0]), s[1] + h/6*(k1[1]+2*k2[1]+2*k3[1]+k4[1]))
truth = []
with open(out, 'w') as fo:
    fo.write('rollout,t,theta,theta_dot\n')
    for r in range(1, n + 1):
        L = rng.uniform(2, 5); th0 = rng.uniform(math.pi/2, 0.9*math.pi)
        truth.append(L)
        s = (th0, 0.0)
        for k in range(128):
            fo.write(f'{r},{k*dt:.2f},{s[0]!r},{s[1]!r}\n')
            for _ in range(10): s = rk4(L, s, dt/10)
print(' '.join(f'{L:.6f}' for L in truth))
