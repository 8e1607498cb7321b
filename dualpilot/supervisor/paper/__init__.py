"""The paper's supervisor (Sec. III-C): attention, decision dynamics Ψ, and its planning.

``attention.py``: Ξ_t, Eq. (KSI), P_t and A_t, Eqs. (dir), (categorical);
``decision.py``: Ψ_t and S_t, Eqs. (Psi), (maxPsi); ``planning.py``: the supervisor in
the mission step (the UAV waits for the chosen system's plan).
"""
