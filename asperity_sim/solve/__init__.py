"""Solve: load paths stepped through increments under mixed control (SPEC §6–§7).

- :mod:`~asperity_sim.solve.solver`: Newton–Raphson for one increment;
- :mod:`~asperity_sim.solve.stepping`: increment sizes, predictors and named failures;
- :mod:`~asperity_sim.solve.run`: the loop of one run; :mod:`~asperity_sim.solve.span` and
  :mod:`~asperity_sim.solve.span_args`: the increments of a stage in one compiled call;
  :mod:`~asperity_sim.solve.driver`:
  :func:`simulate` and :func:`resume`; :mod:`~asperity_sim.solve.run_checkpoint`: a run to a
  checkpoint and back;
- :mod:`~asperity_sim.solve.domain`: where a path-independent law leaves its domain;
- :mod:`~asperity_sim.solve.single`: one contact driven through a local path;
- :mod:`~asperity_sim.solve.pruning`: runs on the height band a path can reach;
- :mod:`~asperity_sim.solve.warmup`: compiling ahead.
"""
