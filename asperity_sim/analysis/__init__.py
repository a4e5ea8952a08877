"""Analysis: what is derived from runs and surfaces.

- :mod:`~asperity_sim.analysis.properties`: joint properties of a run's dataset (strength,
  dilation, stiffness, damping);
- :mod:`~asperity_sim.analysis.gridmethod`: the paper's deterministic grid method, for comparison;
- :mod:`~asperity_sim.analysis.surfaces`: measured and synthetic surfaces, their summits, the fit
  of the model to them and their boundary-element contact.
"""
