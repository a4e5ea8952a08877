"""Output: what a run writes, and how.

- :mod:`~asperity_sim.output.variables`: the registry of output variables (units, long names);
- :mod:`~asperity_sim.output.recorder`: per-step buffers and the Dataset built from them;
- :mod:`~asperity_sim.output.netcdf`: run files written atomically and read back;
- :mod:`~asperity_sim.output.checkpoint`: the checkpoint file format (written atomically, read as
  hostile input);
- :mod:`~asperity_sim.output.plotting`: figures drawn from run files alone.
"""
