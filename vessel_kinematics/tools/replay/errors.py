"""The replay's errors: one line each, never a traceback (``replay: error: <line>``)."""

from __future__ import annotations

from vessel_kinematics.ros.params import ParameterError
from vessel_kinematics.tools.bags import BagError

__all__ = ['error_line', 'EXPECTED', 'one_line', 'ReplayError']


class ReplayError(Exception):
    """A problem with the replay's input or options, reported as one line and a non-zero exit."""


#: The errors the replay expects and reports as they are (any other is 'unexpected').
EXPECTED = (ReplayError, ParameterError, BagError, OSError)


def one_line(text: object) -> str:
    """Return ``text`` on one line (YAML and OS errors span several)."""
    return ' '.join(str(text).split())


def error_line(error: BaseException) -> str:
    """Return the one line ``replay`` prints for ``error`` (without the ``replay: error:``)."""
    if isinstance(error, (ReplayError, ParameterError, BagError)):
        return one_line(error)
    if isinstance(error, OSError):
        where = f' ({error.filename})' if error.filename else ''
        return f'{one_line(error.strerror or error)}{where}'
    return f'unexpected {type(error).__name__}: {one_line(error)}'
