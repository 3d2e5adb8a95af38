"""
The one scalar/array dispatch of the kinematics core, and its return-type rule.

Every function of :mod:`~vessel_kinematics.core.rotation`,
:mod:`~vessel_kinematics.core.quaternion`,
:mod:`~vessel_kinematics.core.geodesy`, :mod:`~vessel_kinematics.core.flow` and
:mod:`~vessel_kinematics.core.frames` decides what it was given with :func:`is_scalar` and
:func:`is_point` below, and shapes its answer by one rule:

Inputs
    A *scalar* is a Python ``int``/``float``, a numpy integer or floating scalar of any width
    (``np.float16`` ... ``np.float64``, ``np.int32`` ...) or a 0-d array of such a dtype. It is
    converted exactly to a float64 before any arithmetic, so ``np.float32(x)`` gives the same
    answer as ``float(np.float32(x))``. A *point* is one vector argument of its core shape
    ((3,) vector, (4,) quaternion, (3, 3) matrix) given as a tuple/list or an array of exactly
    that shape. A call where every argument is a scalar or a point is a *one-point call*; any
    leading (batch) axis makes it a *batch call*.

Outputs
    * batch call: float64 ``ndarray`` (shape = broadcast batch shape + core shape), or a tuple
      of them where the function returns several named quantities ((lat, lon, h), Euler
      angles); ``is_unit`` gives a bool array.
    * one-point call: a quantity without axes (an angle, a radius, a speed) is a Python
      ``float``; several named quantities ((lat, lon, h), (phi, theta, psi)) and the positions
      and velocities of geodesy and flow ((x, y, z), (n, e, d), a current) are a ``tuple`` of
      Python floats (the per-message form the estimator and ``ros.inputs`` unpack); algebraic
      objects (the vectors of rotation, quaternion and frames, quaternions, matrices) are
      float64 ndarrays of the core shape. ``is_unit`` gives a Python ``bool``.

Scalar and batch calls give the same numbers element by element: most functions have one
vectorised numpy body and convert at the end; a separate pure-Python body is kept only for the
per-message hot paths (``bench/bench_quaternion.py``, ``bench/bench_geodesy.py`` measure
what it saves), and the dispatch-consistency tests hold it to the numpy body, including the
wrapping conventions (angles in (-pi, pi] both ways).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ['FloatArray', 'as_float', 'is_point', 'is_scalar', 'one_point', 'stack_matrix',
           'to_float', 'to_floats', 'to_output']

#: The core's array type: float64 ndarrays of any shape.
FloatArray = NDArray[np.float64]

_EXACT = frozenset((float, int))
_NUMPY_SCALARS = (np.floating, np.integer)
_NUMBER_KINDS = frozenset('fiu')


def is_scalar(value: Any) -> bool:
    """Return True for a Python/numpy int or float scalar or a 0-d int/float array."""
    kind = type(value)
    if kind in _EXACT:
        return True
    if isinstance(value, _NUMPY_SCALARS):
        return True
    if isinstance(value, np.ndarray):
        return value.ndim == 0 and value.dtype.kind in _NUMBER_KINDS
    return isinstance(value, (int, float)) and kind is not bool


def one_point(*values: Any) -> bool:
    """Return True when every value is a scalar (see :func:`is_scalar`)."""
    for value in values:
        if type(value) not in _EXACT and not is_scalar(value):
            return False
    return True


def is_point(value: Any, size: int) -> bool:
    """Return True for one vector of ``size`` entries: a tuple/list of scalars or a (size,)."""
    if isinstance(value, (tuple, list)):
        return len(value) == size and one_point(*value)
    if isinstance(value, np.ndarray):
        return value.shape == (size,) and value.dtype.kind in _NUMBER_KINDS
    return False


def as_float(value: Any) -> FloatArray:
    """Return ``value`` as a float64 ndarray (scalars become 0-d arrays)."""
    return np.asarray(value, dtype=np.float64)


def stack_matrix(entries: list[Any], rows: int, cols: int) -> FloatArray:
    """Stack row-major broadcastable entries into a float64 array of shape (..., rows, cols)."""
    parts = np.broadcast_arrays(*[np.asarray(e, dtype=np.float64) for e in entries])
    out = np.stack(parts, axis=-1)
    return out.reshape(out.shape[:-1] + (rows, cols))


def to_float(value: Any) -> float:
    """Return a scalar (Python, numpy or 0-d) as a Python float, exactly."""
    return float(value)


def to_floats(values: Any) -> tuple[float, ...]:
    """Return a sequence of scalars (or a 1-d array) as a tuple of Python floats."""
    return tuple(float(v) for v in values)


def to_output(result: Any, one: bool) -> Any:
    """
    Apply the output rule to a numpy result computed by the vectorised body.

    ``one`` True (a one-point call): a 0-d array becomes a Python float, a (n,) array a tuple
    of Python floats, a tuple of 0-d arrays a tuple of floats. Otherwise the result is returned
    as float64 ndarray(s).
    """
    if isinstance(result, tuple):
        return tuple(to_output(r, one) for r in result)
    arr = np.asarray(result, dtype=np.float64)
    if not one:
        return arr
    if arr.ndim == 0:
        return float(arr)
    return tuple(arr.tolist())
