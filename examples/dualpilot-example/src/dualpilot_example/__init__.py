"""An example dualpilot plug-in (docs/extending.md).

``straight``: a System 1 method, straight at G, braking before a fire
(:mod:`dualpilot_example.straight`); ``proximity``: a supervisor that gives System 2 the
controls near a fire and System 1 elsewhere (:mod:`dualpilot_example.proximity`). Both are
entry points of this package (its pyproject.toml); dualpilot finds them by name.
"""
