# One image for every dualpilot service (see docker-compose.yml):
#   docker compose up --build --exit-code-from supervisor
# The project and its pinned dependencies (pyproject.toml) on python:3.11-slim, or on any
# BASE_IMAGE with python 3.11, `python` and `pip` on PATH and apt (Debian), e.g. the local
# debootstrap base of scripts/compose_check.sh where no image registry is reachable.
ARG BASE_IMAGE=python:3.11-slim
FROM ${BASE_IMAGE}

ENV PYTHONUNBUFFERED=1 \
    PYTHONDONTWRITEBYTECODE=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    MAVLINK20=1 \
    MPLBACKEND=Agg

WORKDIR /app

# OpenMP runtime for the solver wheels (SCIP, HiGHS, OSQP); the rest ships in the wheels
RUN apt-get update \
    && apt-get install -y --no-install-recommends libgomp1 \
    && rm -rf /var/lib/apt/lists/*

# dependencies first (a layer that survives source edits), then the sources
COPY pyproject.toml README.md ./
RUN mkdir -p dualpilot services \
    && touch dualpilot/__init__.py services/__init__.py \
    && pip install . \
    && pip uninstall -y dualpilot
# pyretechnics, the physics fire process's library: built from its sdist against the pinned
# numpy/scipy (scripts/install_pyretechnics.sh), with a C compiler (and the Python headers where
# the base lacks them) that leave the image again
COPY scripts/install_pyretechnics.sh scripts/pyretechnics-requirements.txt ./scripts/
RUN BUILD_DEPS="gcc libc6-dev $(python -c 'import os, sysconfig; \
print("" if os.path.exists(sysconfig.get_paths()["include"] + "/Python.h") else "python3-dev")')" \
    && apt-get update \
    && apt-get install -y --no-install-recommends $BUILD_DEPS \
    && sh scripts/install_pyretechnics.sh python \
    && apt-get purge -y --auto-remove $BUILD_DEPS \
    && rm -rf /var/lib/apt/lists/* /root/.cache/pip
COPY proto ./proto
COPY dualpilot ./dualpilot
COPY services ./services
# runs as root so the supervisor can write to the ./runs bind mount of any host user
RUN pip install --no-deps . && mkdir -p /app/runs
# the Numba kernels compiled once into the image (each service would otherwise compile them);
# the default mission's first 12 steps add its own (the forecast's, the risk zones', the
# lookahead supervisor's lattice): compiled at mission time in a fresh container they made
# System 2's first risk-aware plan miss its 5 s deadline, and the mission another flight
ENV NUMBA_CACHE_DIR=/app/.numba
RUN python -m dualpilot.warmup \
    && python -m dualpilot.cli mission --max-steps 12 --no-figures --quiet --out /tmp/warm \
    && rm -rf /tmp/warm

# MAVLink: offboard link (supervisor → uavsim) and ground station
EXPOSE 14540/udp 14550/udp
CMD ["python", "-m", "services.supervisor", "--help"]
