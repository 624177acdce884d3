"""Reference trajectory of RotorPy 3.0's `Multirotor` (Crazyflie parameters,
aerodynamics on, steady wind) for `host-sim/tests/rotorpy.rs`.

    python3 -m venv /tmp/rotorpy && /tmp/rotorpy/bin/pip install rotorpy==3.0.0
    /tmp/rotorpy/bin/python host-sim/tests/data/rotorpy/make_reference.py

Writes, next to this script:
* `inputs.csv`  -- t,w1,w2,w3,w4: rotor-speed commands in Parapet's (PX4) order, rad/s,
  held for 10 ms each (3 s);
* `reference.csv` -- t,x,y,z,vx,vy,vz,qw,qx,qy,qz,p,q,r: RotorPy's state at each row's
  time, converted to Parapet's frames (world "NED" = RotorPy's (x, -y, -z), body FRD =
  RotorPy's FLU rotated 180 deg about x; the same rotation for both).

RotorPy integrates each 10 ms with solve_ivp RK45 at rtol 1e-11, atol 1e-13, its motor
lag included (tau_m = 0.072 s), the rotors starting at the first command.
Rotor mapping (RotorPy FLU index -> Parapet PX4 rotor): r1 FL -> 3, r2 FR -> 1,
r3 RR -> 4, r4 RL -> 2; RotorPy's rotor_directions [1,-1,1,-1] are then Parapet's
yaw signs (+ for rotors 1, 2).
"""
import copy
import math
import os

import numpy as np
from rotorpy.vehicles.crazyflie_params import quad_params
from rotorpy.vehicles.multirotor import Multirotor

HERE = os.path.dirname(os.path.abspath(__file__))
params = copy.deepcopy(quad_params)
# Parasitic drag on (the shipped Crazyflie file has it 0) so that term is checked too.
params["c_Dx"], params["c_Dy"], params["c_Dz"] = 2e-3, 2e-3, 4e-3
WIND = np.array([1.0, 0.5, -0.2])  # RotorPy world frame (z up), m/s
DT, N = 0.01, 300

w_h = math.sqrt(params["mass"] * 9.81 / (4 * params["k_eta"]))


def command(t):
    """Parapet order [FR, RL, FL, RR]: pitch nose down, then roll, some yaw."""
    pitch = 2.5 * math.sin(2 * math.pi * 0.7 * t)
    roll = 2.0 * math.sin(2 * math.pi * 1.1 * t) * (t > 0.5)
    yaw = 15.0 * (t > 1.5)
    up = 15.0 * math.sin(2 * math.pi * 0.5 * t)
    # FR: front, right; RL: rear, left; FL: front, left; RR: rear, right (FRD).
    fr = w_h + up - pitch - roll + yaw
    rl = w_h + up + pitch + roll + yaw
    fl = w_h + up - pitch + roll - yaw
    rr = w_h + up + pitch - roll - yaw
    return [fr, rl, fl, rr]


def to_rotorpy(w):
    fr, rl, fl, rr = w
    return np.array([fl, fr, rr, rl])  # r1 FL, r2 FR, r3 RR, r4 RL


cmds = [command(k * DT) for k in range(N + 1)]
state = {
    "x": np.zeros(3),
    "v": np.zeros(3),
    "q": np.array([0.0, 0.0, 0.0, 1.0]),
    "w": np.zeros(3),
    "wind": WIND.copy(),
    "rotor_speeds": to_rotorpy(cmds[0]),
}
quad = Multirotor(
    params,
    initial_state=state,
    control_abstraction="cmd_motor_speeds",
    aero=True,
    integrator_kwargs={"method": "RK45", "rtol": 1e-11, "atol": 1e-13},
)


def row(t, s):
    x, v, q, w = s["x"], s["v"], s["q"], s["w"]
    vals = [t, x[0], -x[1], -x[2], v[0], -v[1], -v[2], q[3], q[0], -q[1], -q[2], w[0], -w[1], -w[2]]
    return ",".join(f"{a:.12g}" for a in vals)


with open(os.path.join(HERE, "inputs.csv"), "w") as f:
    f.write("t,w1,w2,w3,w4\n")
    for k, c in enumerate(cmds):
        f.write(f"{k * DT:.2f}," + ",".join(f"{x:.6f}" for x in c) + "\n")
# Re-read the rounded commands so both simulators get exactly the same numbers.
cmds = [[float(x) for x in line.split(",")[1:]] for line in open(os.path.join(HERE, "inputs.csv")).read().split("\n")[1:] if line]
state["rotor_speeds"] = to_rotorpy(cmds[0])
rows = [row(0.0, state)]
for k in range(N):
    state = quad.step(state, {"cmd_motor_speeds": to_rotorpy(cmds[k])}, DT)
    rows.append(row((k + 1) * DT, state))
with open(os.path.join(HERE, "reference.csv"), "w") as f:
    f.write("t,x,y,z,vx,vy,vz,qw,qx,qy,qz,p,q,r\n" + "\n".join(rows) + "\n")
print("final", rows[-1])
