"""Error of the `mdr` law against the number of springs k (single contact).

Errors, relative to mu f_n (forces) or to the closed-form loop energy:
- monotonic Cattaneo–Mindlin (delta_s to 1.3 delta_slip at constant delta_n): max force error;
- Masing loop at amplitude 0.5 delta_slip: error of the dissipation of a stable cycle
  against the closed-form Mindlin–Deresiewicz loop area (quadrature of the Masing branches);
- shear turning by 90° and 120° after 0.6 delta_slip: max force difference to k = 256.

Run:   python benchmarks/mdr_k_convergence.py
Writes outputs/mdr_k_convergence.json and outputs/mdr_k_convergence.md.  About 3 seconds
(2.6 s measured on this 2-core machine, one numba thread, warm cache).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
from scipy import integrate

from asperity_sim import single_contact

OUT = Path(__file__).resolve().parent.parent / "outputs"
R, G, NU, MU = 1e-4, 30e9, 0.3, 0.5
E_STAR = G / (1 - NU)
LAM = (2 - NU) / (2 * (1 - NU))
DN = 1e-6
D_SLIP = LAM * MU * DN
F_N = 4 / 3 * E_STAR * math.sqrt(R) * DN**1.5


def f_cm(d):
    x = np.minimum(np.abs(d) / D_SLIP, 1.0)
    return np.sign(d) * MU * F_N * (1 - (1 - x) ** 1.5)


def ramp(a, b, m):
    return np.linspace(a, b, m + 1)[1:]


def with_normal(tang):
    tang = np.atleast_2d(np.asarray(tang, dtype=float).T).T
    if tang.shape[1] == 1:
        tang = np.c_[tang, np.zeros(len(tang))]
    return np.r_[np.c_[ramp(0, DN, 10), np.zeros((10, 2))], np.c_[np.full(len(tang), DN), tang]]


def monotonic(k):
    t = ramp(0, 1.3 * D_SLIP, 130)
    ds = single_contact(with_normal(t), R, G, NU, MU, k=k)
    return float(np.abs(ds.force.values[10:, 1] - f_cm(t)).max() / (MU * F_N))


def loop(k, amp=0.5 * D_SLIP, m=400):
    t = np.r_[ramp(0, amp, m // 2), ramp(amp, -amp, m), ramp(-amp, amp, m)]
    ds = single_contact(with_normal(t), R, G, NU, MU, k=k)
    D = ds.dissipation.values
    got = D[-1] - D[10 + m // 2 - 1]
    up = lambda d: -f_cm(amp) + 2 * f_cm((d + amp) / 2)  # noqa: E731
    down = lambda d: f_cm(amp) - 2 * f_cm((amp - d) / 2)  # noqa: E731
    W = integrate.quad(lambda d: up(d) - down(d), -amp, amp, epsrel=1e-10)[0]
    return float(abs(got - W) / W)


def turn_forces(angle, k):
    a = math.radians(angle)
    leg1 = np.c_[ramp(0, 0.6 * D_SLIP, 30), np.zeros(30)]
    leg2 = np.array([0.6 * D_SLIP, 0.0]) + ramp(0, 0.8 * D_SLIP, 40)[:, None] * np.array([math.cos(a), math.sin(a)])
    return single_contact(with_normal(np.r_[leg1, leg2]), R, G, NU, MU, k=k).force.values


def main():
    ks = [8, 16, 32]
    rows = {"monotonic_force": [monotonic(k) for k in ks], "loop_energy": [loop(k) for k in ks]}
    for angle in (90, 120):
        ref = turn_forces(angle, 256)
        rows[f"turn_{angle}_force"] = [float(np.abs(turn_forces(angle, k) - ref).max() / (MU * F_N)) for k in ks]
    OUT.mkdir(exist_ok=True)
    (OUT / "mdr_k_convergence.json").write_text(json.dumps({"k": ks, **rows}, indent=2))
    labels = {"monotonic_force": "monotonic Cattaneo–Mindlin, max force error / (mu f_n)",
              "loop_energy": "Masing loop (A = 0.5 delta_slip), dissipation error / closed form",
              "turn_90_force": "90° turn, max force difference to k = 256 / (mu f_n)",
              "turn_120_force": "120° turn, max force difference to k = 256 / (mu f_n)"}
    lines = ["| quantity | k = 8 | k = 16 | k = 32 |", "|---|---|---|---|"]
    for key, vals in rows.items():
        lines.append(f"| {labels[key]} | " + " | ".join(f"{v:.2e}" for v in vals) + " |")
    table = "\n".join(lines)
    (OUT / "mdr_k_convergence.md").write_text(table + "\n")
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
