"""The fork server's first import: the compute-thread limits of every service.

docker-compose.yml gives every service ``OPENBLAS_NUM_THREADS`` and ``OMP_NUM_THREADS`` (its
shared environment, ``x-env``); BLAS reads them once, when numpy loads it. A forked service
inherits the server's BLAS, so the server takes the same values before anything imports
numpy (:mod:`services.forking.warm` comes next). It reads the file's ``x-env`` with yaml
itself: :func:`services.launch.compose.load_compose` is in a package that imports numpy.
"""

from __future__ import annotations

import os
from pathlib import Path

import yaml

COMPOSE = Path(__file__).resolve().parent.parent.parent / "docker-compose.yml"
#: the variables BLAS and OpenMP read when they load
THREAD_LIMITS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")

_shared = yaml.safe_load(COMPOSE.read_text())["x-env"]
for _name in THREAD_LIMITS:
    os.environ[_name] = str(_shared[_name])
