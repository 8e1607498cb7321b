#!/bin/sh
# Install pyretechnics (scripts/pyretechnics-requirements.txt) into the environment of PYTHON
# (default: python) unless that version is already importable there.
#
# Its sdist pins numpy~=1.26 and scipy~=1.12, and its shipped C files were generated against
# numpy 1.x; this project pins numpy 2 and scipy 1.17 (pyproject.toml). So it is built
# --no-deps --no-build-isolation against the installed numpy with a pinned Cython, the C files
# regenerated (CYTHON_FORCE_REGEN=1). Its runtime needs are numpy, scipy and sortedcontainers
# (pinned in pyproject.toml); rasterio is only imported by pyretechnics.load_landfire, which the
# project does not use. Needs a C compiler and the Python headers; the build takes ~4 min.
set -eu
PY=${1:-python}
REQS="$(dirname "$0")/pyretechnics-requirements.txt"
VERSION=$(sed -n 's/^pyretechnics==\([^ ]*\).*/\1/p' "$REQS")
if "$PY" - "$VERSION" <<'PYEOF' 2>/dev/null
import importlib.metadata, sys
assert importlib.metadata.version("pyretechnics") == sys.argv[1]
import pyretechnics.eulerian_level_set  # noqa: F401  (the compiled extension loads)
PYEOF
then
    exit 0
fi
"$PY" -m pip install --quiet Cython==3.0.12 setuptools==84.2.1
CYTHON_FORCE_REGEN=1 "$PY" -m pip install --quiet --no-deps --no-build-isolation \
    --require-hashes -r "$REQS"
"$PY" -c "import pyretechnics.eulerian_level_set"
