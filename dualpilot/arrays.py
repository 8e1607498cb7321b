"""Array type aliases of the core: float arrays, and arrays of any dtype."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

#: A float array (positions in m, velocities in m/s, forces in N, ...).
Array = NDArray[np.float64]
#: An array of any dtype (float, int or bool), for index and mask work.
AnyArray = NDArray[Any]
