"""What the fork server loads before it forks a service (services/forking/server.py).

Importing this module imports every service's modules and warms the Numba kernels their
first plans and checks would load (:func:`dualpilot.warmup.warm_up_3d` for both planning
systems, which runs :func:`dualpilot.warmup.warm_up` first; the supervisor's
:func:`services.supervisor.warm.warm_kernels`), so that a forked service starts with them
in memory; then it collects once and freezes the heap (what each service does at its start,
:func:`services.common.bus.service.settle_heap`), so a forked service's collections walk only
its own objects. It starts no thread that outlives it and opens no Zenoh session or socket: a fork
copies the server as it is.
"""

from __future__ import annotations

import importlib

from dualpilot.warmup import warm_up_3d
from services.common.bus.service import settle_heap
from services.supervisor.warm import warm_kernels

#: the services' entry modules (each imports its service's modules; the router, services/router.py,
#: is a module run as __main__ itself and imports nothing these do not)
SERVICES = ("services.ews.__main__", "services.system1.__main__",
            "services.system2.__main__", "services.uavsim.__main__",
            "services.supervisor.__main__", "services.viewer.__main__")

for _name in SERVICES:
    importlib.import_module(_name)
warm_up_3d()  # the planar kernels first (warm_up), then the 3-D ones
warm_kernels()
# what every service does once started, done here once: a forked service's collection then
# walks only the objects it made itself, and never writes the server's objects' headers
# (which would copy their pages into each child)
settle_heap()
