"""Array types and callbacks shared by the core packages (and the services that call them).

Array aliases name the dtype only; shapes, frames and units are stated in each function's docstring.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ["F32", "F64", "I16", "I64", "U8", "BoolArr", "ProgressFn"]

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]
I64 = NDArray[np.int64]
I16 = NDArray[np.int16]
U8 = NDArray[np.uint8]
BoolArr = NDArray[np.bool_]

#: Progress of long work: ``progress(stage, fraction)`` with a short stage name (e.g. ``"odometry"``) and
#: the fraction of that stage done, in [0, 1].
ProgressFn = Callable[[str, float], None]
