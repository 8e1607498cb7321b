"""The layout of the multirotor's state vector (dualpilot.plant.multirotor).

Indices of position p (m), velocity v (m/s), thrust axis b₃, body rate ω (rad/s),
collective thrust T (N), the velocity integrator, the previous velocity and the low-passed
velocity derivative, each (but T) three entries. A module of its own, without Numba, so
that a plant's state can be read without loading the compiled flight.
"""

#: Layout of the vehicle's state vector (see :func:`~dualpilot.plant.multirotor.hover_vector`).
P, V, B3, W, T, VINT, VPREV, VDOT = 0, 3, 6, 9, 12, 13, 16, 19
STATE_LEN = 22
