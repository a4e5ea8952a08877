"""User interface: the ``asperity-sim`` command line and progress bars.

- :mod:`~asperity_sim.ui.cli`: the entry point; :mod:`~asperity_sim.ui.parser` its grammar;
  :mod:`~asperity_sim.ui.commands` the commands; :mod:`~asperity_sim.ui.files` the files they
  check, read and write; :mod:`~asperity_sim.ui.reports` the text reports;
  :mod:`~asperity_sim.ui.exits` errors and exit statuses;
- :mod:`~asperity_sim.ui.progress`: progress bars on a terminal.
"""
