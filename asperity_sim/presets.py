"""The four parameter sets of the paper's Table 1, in SI (SPEC §1).

e is not given in the paper; SPEC §1 fixes e = 1 and b = c = d = 0.
"""

from .params import InterfaceParams

R1 = InterfaceParams(N=200e6, R_m=50e-6, R_sigma=15e-6, mu=1.0, G=80e9, nu=0.3,
                     r_o=0.0, alpha=6.14, beta=3.52e-6)
"""Rough interface (Table 1, R1)."""

S1 = InterfaceParams(N=200e6, R_m=75e-6, R_sigma=10e-6, mu=1.0, G=80e9, nu=0.3,
                     r_o=0.0, alpha=3.82, beta=1.15e-6)
"""Smooth interface (Table 1, S1)."""

R2 = InterfaceParams(N=0.2240e6, R_m=8.82e-3, R_sigma=0.30e-3, mu=1.0, G=31.8e9, nu=0.152,
                     r_o=0.10e-3, alpha=7.20, beta=0.05e-3)
"""Rough marble interface (Table 1, R2)."""

S2 = InterfaceParams(N=0.2034e6, R_m=8.18e-3, R_sigma=0.20e-3, mu=1.0, G=31.8e9, nu=0.152,
                     r_o=0.12e-3, alpha=6.77, beta=0.03e-3)
"""Smooth marble interface (Table 1, S2)."""

TABLE1 = {"R1": R1, "S1": S1, "R2": R2, "S2": S2}

TITLES = {"R1": "rough interface", "S1": "smooth interface", "R2": "rough marble interface",
          "S2": "smooth marble interface"}
"""What each preset describes (the paper's Table 1)."""
