"""Runs described in files: scenes, sweeps of scenes, and the strength and cyclic curves of joints.

- :mod:`~asperity_sim.runs.scene`: one run in TOML;
- :mod:`~asperity_sim.runs.sweep`: a grid of scenes with replicas; :mod:`~asperity_sim.runs.engine`
  runs them (serially or on Dask) and :mod:`~asperity_sim.runs.ensemble` makes their dataset;
- :mod:`~asperity_sim.runs.envelope`: strength envelopes and cyclic stiffness and damping;
- :mod:`~asperity_sim.runs.figures`: their figures.
"""
