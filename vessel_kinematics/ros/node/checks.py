"""
Sanity checks of legal but harmful run-time parameter changes, against what the node has seen.

Each parameter is checked against its range by the one table (:mod:`..params`); some values in
range still harm the estimate given the vessel's state:

* an ``origin`` farther than :data:`MAX_ORIGIN_DISTANCE` from the vessel's current position
  (or, before there is one, from the first fix received): the map frame's tangent plane would
  be off by kilometres where the vessel is (an origin at the pole for a vessel at 63° N puts
  ``fix/filtered`` 275 km off);
* a ``max_gap`` shorter than :data:`GAP_PERIODS` periods of the fastest input received: every
  step between two messages would be a gap, and nothing would be integrated.

The distance is the great circle on the mean Earth radius (haversine): 0.5 % at most off the
ellipsoid's geodesic, which is plenty for a bound of 100 km. ROS-free.
"""

from __future__ import annotations

import math
from typing import Mapping

from vessel_kinematics.ros.params import NavigatorParams

__all__ = ['GAP_PERIODS', 'great_circle', 'MAX_ORIGIN_DISTANCE', 'RunTimeChecks']

#: Farthest a new origin may be from the vessel (m).
MAX_ORIGIN_DISTANCE = 100_000.0
#: ``max_gap`` must be at least this many periods of the fastest input.
GAP_PERIODS = 3.0
#: The mean Earth radius (m, IUGG R1).
MEAN_RADIUS = 6_371_008.8


def great_circle(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Return the great-circle distance (m) between two points given in degrees (haversine)."""
    p1, p2 = math.radians(lat1), math.radians(lat2)
    dp, dl = p2 - p1, math.radians(lon2 - lon1)
    h = math.sin(dp / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2.0 * MEAN_RADIUS * math.asin(min(1.0, math.sqrt(h)))


class RunTimeChecks:
    """What the checks know of the vessel: the first fix, the inputs' measured rates."""

    def __init__(self) -> None:
        #: The first fix received (lat, lon in degrees), None before one.
        self.first_fix: tuple[float, float] | None = None
        #: Measured rate per input (Hz), from :meth:`observe`.
        self.rates: dict[str, float] = {}
        self._last: dict[str, tuple[int, int | None]] | None = None

    def observe(self, accepted: Mapping[str, int], stamps: Mapping[str, int | None]) -> None:
        """
        Take the inputs' accepted counts and the stamps (ns) of their last accepted messages.

        The rate of an input is its messages per second of its own stamps between two calls
        (the sensor's rate, whatever the delivery's bursts), kept while it goes on.
        """
        now = {name: (n, stamps.get(name)) for name, n in accepted.items() if name in stamps}
        if self._last is not None:
            for name, (n, stamp) in now.items():
                n0, stamp0 = self._last.get(name, (0, None))
                if stamp is not None and stamp0 is not None and stamp > stamp0 and n > n0:
                    self.rates[name] = (n - n0) / ((stamp - stamp0) * 1e-9)
        self._last = now

    def problem(self, old: NavigatorParams, new: NavigatorParams,
                position_deg: tuple[float, float] | None) -> str | None:
        """Return why ``new`` may not replace ``old`` now, or None (position: lat, lon deg)."""
        if new.origin != old.origin and all(math.isfinite(c) for c in new.origin[:2]):
            where, label = position_deg, "the vessel's current position"
            if where is None:
                where, label = self.first_fix, 'the first fix'
            if where is not None:
                distance = great_circle(new.origin[0], new.origin[1], *where)
                if distance > MAX_ORIGIN_DISTANCE:
                    return (f"parameter 'origin': {distance / 1e3:.0f} km from {label}, more "
                            f'than {MAX_ORIGIN_DISTANCE / 1e3:.0f} km: the map frame would be '
                            'off where the vessel is (refused)')
        if new.max_gap != old.max_gap and self.rates:
            name, rate = max(self.rates.items(), key=lambda item: item[1])
            floor = GAP_PERIODS / rate
            if new.max_gap < floor:
                return (f"parameter 'max_gap': {new.max_gap:g} s is shorter than "
                        f'{GAP_PERIODS:g} periods of {name} ({rate:.0f} Hz): at least '
                        f'{floor:.3g} s, or every step between two messages is a gap')
        return None
