"""Kernels: the sums over the population's contacts, compiled once per law (SPEC §6).

- :mod:`~asperity_sim.kernels.layout`: the arrays' layouts and the ordered sum of partial rows;
- :mod:`~asperity_sim.kernels.contact` and :mod:`~asperity_sim.kernels.reach`: one contact's
  angle, force and tangent, and the tests that skip asperities out of reach;
- :mod:`~asperity_sim.kernels.reductions` (path-independent laws), :mod:`~asperity_sim.kernels.history`
  (the trial of a history law) and :mod:`~asperity_sim.kernels.commit`: templates, compiled for a
  law by :mod:`~asperity_sim.kernels.specialise`;
- :mod:`~asperity_sim.kernels.loop` with :mod:`~asperity_sim.kernels.loop_path_independent` and
  :mod:`~asperity_sim.kernels.loop_history`: the increments of a stage compiled whole (templates), and
  :mod:`~asperity_sim.kernels.domain`: the per-step test of a path-independent law's domain;
- :mod:`~asperity_sim.kernels.evaluate`: :func:`evaluate`, the interface response at one
  displacement, and :mod:`~asperity_sim.kernels.state`: the committed contact state and its commit.
"""
