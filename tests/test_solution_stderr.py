"""Error bars under mixed control: the delta-method standard errors match replica scatter."""

import math

import numpy as np
import pytest

from asperity_sim import paths, presets, simulate

REPLICAS = 40


@pytest.mark.statistical
@pytest.mark.slow
def test_stderr_of_solved_closure_and_shear_stress_match_replicas():
    path = paths.constant_normal_shear(500e6, 4e-6, increments=2, normal_increments=3)
    finals = [simulate(presets.S1, path, n=4000, seed=1000 + i).isel(step=-1) for i in range(REPLICAS)]
    d1 = np.array([float(f.displacement.sel(axis=1)) for f in finals])
    s2 = np.array([float(f.stress.sel(axis=2)) for f in finals])
    se_d1 = np.mean([float(f.displacement_stderr.sel(axis=1)) for f in finals])
    se_s2 = np.mean([float(f.stress_stderr.sel(axis=2)) for f in finals])
    # sigma_1 is held exactly, so its error moved into Delta_1 and into sigma_2 through T_21
    assert all(float(f.stress_stderr.sel(axis=1)) == 0.0 for f in finals)
    tol = 4 * math.sqrt(1 / (2 * (REPLICAS - 1)))  # 4 s.e. of a sample standard deviation
    assert abs(d1.std(ddof=1) / se_d1 - 1) < tol
    assert abs(s2.std(ddof=1) / se_s2 - 1) < tol
