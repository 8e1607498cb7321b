"""Evaluating the planners and the supervisor, on top of the core's mission step.

- :mod:`~dualpilot.evaluation.missions`: one mission of an evaluation (seed pair, task, row);
- :mod:`~dualpilot.evaluation.results`, :mod:`~dualpilot.evaluation.runner`,
  :mod:`~dualpilot.evaluation.stats`: the run directory, running tasks (Dask), summary numbers;
- :mod:`~dualpilot.evaluation.evaluate`, :mod:`~dualpilot.evaluation.sweep`:
  ``dualpilot evaluate`` (Fig. r5) and ``dualpilot sweep`` (a grid of readings);
- :mod:`~dualpilot.evaluation.instances`, :mod:`~dualpilot.evaluation.bench`: seeded
  planning instances and ``dualpilot bench``;
- :mod:`~dualpilot.evaluation.bound`: P(System 1 in control | d, t) of the paper's
  supervisor, exactly (``dualpilot bound``).
"""
