"""Sampling: a population of discrete asperities drawn from the interface's densities (SPEC §2–§3).

- :mod:`~asperity_sim.sampling.distributions`: inverse CDFs of heights, radii and orientations;
- :mod:`~asperity_sim.sampling.sobol`: scrambled Sobol' points (randomised QMC);
- :mod:`~asperity_sim.sampling.draws`: the random points and their mapping (the only user of
  random generators);
- :mod:`~asperity_sim.sampling.population`: :class:`Population`, struct-of-arrays sorted by height;
- :mod:`~asperity_sim.sampling.reach` and :mod:`~asperity_sim.sampling.band`: which heights can
  touch at a displacement, and along a load path.
"""
