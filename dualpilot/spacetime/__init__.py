"""Space-time search: paths through fires whose future is known, under Eq. (1).

:mod:`~dualpilot.spacetime.lattice` is a time-expanded A* over a lattice of Eq. (1)'s
states against boxes that change every sub-step; :mod:`~dualpilot.spacetime.plan`
plans with it from a moving state and checks plans against such boxes;
:mod:`~dualpilot.spacetime.smooth` smooths a lattice plan inside a tube around it;
:mod:`~dualpilot.spacetime.known` builds the boxes of what a supervisor knows (the
current hulls and the forecast's risky cells). The clairvoyant oracle
(:mod:`dualpilot.oracle`) runs the same search on the true future.
"""
