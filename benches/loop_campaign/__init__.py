"""Independent evaluation campaign for ``gmsfric loop`` (see README.md in this folder).

Modules: :mod:`.rigs` (simulators, trajectories, logging, EMPS planting), :mod:`.truth`
(ground truth by least squares on the true regression columns), :mod:`.cases` (the seeded case
list and the CI subset), :mod:`.score` (confusion matrix and rates) and :mod:`.run` (the CLI).
"""
