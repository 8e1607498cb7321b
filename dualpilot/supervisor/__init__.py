"""The supervisors of the cognitive controller (Sec. III-C): who decides what flies.

``interface.py`` is what a supervisor is to the mission step (:class:`Supervisor`,
:class:`StepView`, :class:`Planned`) and to the registry (:class:`SupervisorEntry`);
``registry.py`` builds one by name (the built-ins and those installed packages add:
entry-point group ``dualpilot.supervisors``). Each kind is a subpackage with its rule
and its planning side by side: ``paper/`` (the attention, Eqs. KSI, dir, categorical;
the decision dynamics, Eqs. Psi, maxPsi; the UAV waits for the chosen plan),
``concurrent/`` (System 2 deliberates while the UAV flies) and ``lookahead/`` (the
concurrent choice, guarded by the known future).
"""
