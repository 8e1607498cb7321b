"""The clairvoyant oracle: per mission, is reaching G possible at all?

A yardstick for every controller (docs/yardstick.md). For one mission (its
seed, reading and scenario) the oracle knows the whole fire future and answers

* **feasible**: a witness trajectory found by a space-time search over a lattice of
  Eq. (1)'s states against the known future regions
  (:mod:`~dualpilot.oracle.search`), then flown through the one mission step with
  every failure rule (:mod:`~dualpilot.oracle.witness`);
* **impossible**: a sound certificate, the positions any controller can occupy,
  over-approximated on a grid, never reach G without a failure
  (:mod:`~dualpilot.oracle.certificate`);
* **unknown**: neither, within its budget.

The fire future is the mission's own fire stream run as the oracle flies
(:mod:`~dualpilot.oracle.future`); :func:`~dualpilot.oracle.oracle.solve` ties the
parts together.
"""
