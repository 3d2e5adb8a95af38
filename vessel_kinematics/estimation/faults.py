"""
Instrument faults: a frozen compass, a stuck log, a repeated sample; each test and threshold.

Real boats have these every season, and each passes as truth unless something tests it: a
compass frozen at 196° in a turn gives 45-90° of sideslip. The tests compare an instrument
with what the others say of the same motion, over a window, and refuse its samples with
``frozen_input`` while the fault lasts (:class:`~.records.Reason`):

``FrozenHeading``
    The compass heading stays within :data:`~.config.FROZEN_HEADING_TOLERANCE` (1°, one count
    of an integer-degree compass) of the value it took at the start of the run, while the gyro
    turns the vessel by :data:`~.config.FROZEN_HEADING_TURN` (10°) since then, or, with no
    gyro, the fixes' course over ground (over 50 m, at 2 m/s or more) turns by
    :data:`~.config.FROZEN_HEADING_COG_TURN` (45°); the gyro's turn is counted over the last
    :data:`~.config.FROZEN_HEADING_WINDOW`
    (10 s), so that its bias (0.05°/s: 0.5° in the window) never adds up to a false alarm on a
    steady heading. A live compass follows both; a frozen one does neither.

    A compass that jumps by more than :data:`~.config.FROZEN_HEADING_JUMP` (45°) from its last
    live sample, faster than :data:`~.config.FROZEN_HEADING_JUMP_RATE` (45°/s), and holds
    that value is frozen there, at any speed and with no gyro: no hull turns so, and a glitch
    that holds (a yacht's compass leaving the harbour read 196° for 30 s while the boat
    turned from 308° to 261°) passes every other test at a walking pace. It is live again
    when it turns on from that value, when the gyro turned with the jump, when the fixes'
    course confirms it (within 45°, over 50 m at 2 m/s or more), or after
    :data:`~.config.FROZEN_HEADING_JUMP_HOLD` (60 s): one sample of a glitch costs one
    sample. Not in the compass's first :data:`~.config.FROZEN_HEADING_WINDOW` (10 s): an
    AHRS may come up at a default heading and jump to the vessel's once its magnetometer
    is in.
``StuckLog``
    The log's reading stays within :data:`~.config.FROZEN_LOG_TOLERANCE` (0.05 m/s, a log's
    0.1 kn resolution) of the value it took at the start of the run, while the speed through
    the water that the fixes give, |V_GNSS − c₀| (c₀ the current estimated at the run's start,
    V_GNSS the fixes' velocity over :data:`~.config.FROZEN_LOG_WINDOW`), changes by
    :data:`~.config.FROZEN_LOG_SPEED_CHANGE` (1 m/s, about 2 kn). A log stuck at zero while
    the boat turns is caught too: the current does not turn with the boat.
``repeated``
    A sample with the stamp and the values of the one before it on that input: a driver
    sending the same message twice.

The estimator measures the false-alarm rates on the recorded voyages of the test suite
(``test/test_faults.py``); the thresholds are well above the noise of any of them.
"""

from __future__ import annotations

from array import array
from collections import deque
import math
from typing import Sequence

import numpy as np

from vessel_kinematics.core.flow import ssa
from vessel_kinematics.estimation.config import (FROZEN_COG_BASELINE, FROZEN_COG_MIN_SPEED,
                                                 FROZEN_HEADING_COG_TURN, FROZEN_HEADING_JUMP,
                                                 FROZEN_HEADING_JUMP_HOLD,
                                                 FROZEN_HEADING_JUMP_RATE,
                                                 FROZEN_HEADING_TOLERANCE, FROZEN_HEADING_TURN,
                                                 FROZEN_HEADING_WINDOW,
                                                 FROZEN_LOG_SPEED_CHANGE, FROZEN_LOG_TOLERANCE,
                                                 FROZEN_LOG_WINDOW)

__all__ = ['FrozenHeading', 'GnssTrack', 'StuckLog', 'repeated']

#: How long (s) the track of fixes is kept: the course's baseline at a walking pace.
_TRACK_SPAN = 60.0
#: The frozen-compass window keeps one gyro turn per 0.1 s (ns): its start is then known to
#: 1 % of the window, and a 400 Hz compass keeps 100 samples, not 4000 (the state history
#: copies the estimator ten times a second).
_WINDOW_STEP_NS = 100_000_000


def repeated(last: tuple | None, now: tuple) -> bool:
    """Return True when ``now`` (stamp, values...) is the sample ``last`` again."""
    return last is not None and last == now


class GnssTrack:
    """
    The base's positions from the recent fixes (map N, E, m), for the fault tests.

    Kept as one flat ``array('d')`` of (t s, N m, E m) triples: the state history copies the
    estimator ten times a second, and 60 s of 10 Hz fixes pickle in a few microseconds as
    bytes, against about 60 us as 600 tuples.
    """

    __slots__ = ('points', 'course')

    def __init__(self) -> None:
        self.points = array('d')
        #: The course over ground (rad) over the last :data:`~.config.FROZEN_COG_BASELINE` m,
        #: found at each fix; None below :data:`~.config.FROZEN_COG_MIN_SPEED` over that
        #: stretch, or before it is covered.
        self.course: float | None = None

    def add(self, t: float, n: float, e: float) -> None:
        """Add a fix's base position at time ``t`` (s)."""
        pts = self.points
        if pts and t <= pts[-3]:
            return
        pts.extend((t, n, e))
        old = 0
        while t - pts[old] > _TRACK_SPAN:
            old += 3
        if old:
            del pts[:old]
        self.course = None
        for i in range(len(pts) - 3, -1, -3):
            t0, n0, e0 = pts[i], pts[i + 1], pts[i + 2]
            dn, de = n - n0, e - e0
            d2 = dn * dn + de * de
            if d2 >= FROZEN_COG_BASELINE ** 2:
                if d2 >= (FROZEN_COG_MIN_SPEED * (t - t0)) ** 2:
                    self.course = math.atan2(de, dn)
                break

    def velocity(self, t: float, window: float = FROZEN_LOG_WINDOW) -> tuple[float, float] | None:
        """Return the fixes' least-squares velocity, N and E (m/s), over the last ``window`` s."""
        pts = np.frombuffer(self.points, dtype=float).reshape(-1, 3)
        arr = pts[(t - window <= pts[:, 0]) & (pts[:, 0] <= t)]
        if len(arr) < 3 or arr[-1, 0] - arr[0, 0] < 0.5 * window:
            return None
        tt = arr[:, 0] - arr[:, 0].mean()
        den = float(tt @ tt)
        return float(tt @ arr[:, 1]) / den, float(tt @ arr[:, 2]) / den


class FrozenHeading:
    """The frozen-compass test (see the module notes); the gyro's turn is fed in by the caller."""

    __slots__ = ('value', 'turn', 'course0', 'frozen', 'gyro', 'window', 'heard', 'live',
                 'jump')

    def __init__(self) -> None:
        self.value: float | None = None
        #: The stamp (ns) of the first sample: no jump is told in the first window after it.
        self.heard: int | None = None
        #: The last live sample: (stamp ns, ψ rad, the gyro's turn since the run started).
        self.live: tuple[int, float, float] | None = None
        #: A jump held: (stamp ns of its first sample, ψ rad, the gyro's turn then).
        self.jump: tuple[int, float, float] | None = None
        #: The gyro's turn since the run started (rad), and whether a gyro fed it.
        self.turn = 0.0
        self.gyro = False
        #: (stamp ns, turn) at the run's compass samples of the last window.
        self.window: deque[tuple[int, float]] = deque()
        self.course0: float | None = None
        self.frozen = False

    def rate(self, dt: float, psi_rate: float) -> None:
        """Integrate the gyro's heading rate ψ̇ (rad/s) over ``dt`` s."""
        self.turn += psi_rate * dt
        self.gyro = True

    def heading(self, stamp_ns: int, psi: float, course: float | None,
                offset: float = 0.0) -> str | None:
        """
        Take a compass heading ψ (rad); return why it is frozen, or None for a live one.

        ``course`` the fixes' course over ground now (:attr:`GnssTrack.course`), or None;
        ``offset`` what turns ψ into the map's heading, as the course is (rad).
        """
        jumped = self._jumped(stamp_ns, psi, course, offset)
        if jumped is not None:
            return jumped
        why = self._run(stamp_ns, psi, course)
        if why is None:
            self.live = (stamp_ns, psi, self.turn)
        return why

    def _jumped(self, stamp_ns: int, psi: float, course: float | None,
                offset: float) -> str | None:
        """Return why ψ is a jump held (see the module notes), or None."""
        live, jump = self.live, self.jump
        if self.heard is None:
            self.heard = stamp_ns
        if live is None or (live[0] - self.heard) * 1e-9 < FROZEN_HEADING_WINDOW:
            return None     # a compass just started may settle on the vessel's heading in a jump
        if jump is None:
            change = abs(ssa(psi - live[1]))
            dt = (stamp_ns - live[0]) * 1e-9
            if change <= FROZEN_HEADING_JUMP or change <= FROZEN_HEADING_JUMP_RATE * dt:
                return None
            jump = self.jump = (stamp_ns, psi, self.turn)
        elif (abs(ssa(psi - jump[1])) > FROZEN_HEADING_TOLERANCE
              or (stamp_ns - jump[0]) * 1e-9 > FROZEN_HEADING_JUMP_HOLD):
            self.jump = None
            return None
        if ((course is not None and abs(ssa(course - psi - offset)) < FROZEN_HEADING_COG_TURN)
                or (self.gyro and abs(ssa(jump[1] - live[1] - self.turn + live[2]))
                    < FROZEN_HEADING_JUMP)):
            self.jump = None        # the fixes' course agrees with it, or the gyro turned with it
            return None
        return (f'compass jumped {math.degrees(ssa(jump[1] - live[1])):+.0f} deg to '
                f'{math.degrees(jump[1]) % 360.0:.1f} deg and holds there')

    def _run(self, stamp_ns: int, psi: float, course: float | None) -> str | None:
        """Test the run of one value against the gyro's or the course's turn."""
        if self.value is None or abs(ssa(psi - self.value)) > FROZEN_HEADING_TOLERANCE:
            self.value, self.turn, self.gyro = psi, 0.0, False
            self.course0, self.frozen = course, False
            self.window.clear()
            self.window.append((stamp_ns, 0.0))
            return None
        if self.frozen:
            return 'compass frozen'
        window = self.window
        if stamp_ns - window[-1][0] >= _WINDOW_STEP_NS:
            window.append((stamp_ns, self.turn))
        while (stamp_ns - window[0][0]) * 1e-9 > FROZEN_HEADING_WINDOW:
            window.popleft()
        if self.gyro and abs(self.turn - window[0][1]) >= FROZEN_HEADING_TURN:
            self.frozen = True
            return (f'compass frozen at {math.degrees(self.value) % 360.0:.1f} deg while the '
                    f'gyro turned {math.degrees(self.turn):+.0f} deg')
        if not self.gyro and course is not None:
            if self.course0 is None:
                self.course0 = course
            elif abs(ssa(course - self.course0)) >= FROZEN_HEADING_COG_TURN:
                self.frozen = True
                return (f'compass frozen at {math.degrees(self.value) % 360.0:.1f} deg while '
                        f'the course over ground turned '
                        f'{math.degrees(ssa(course - self.course0)):+.0f} deg')
        return None

    def correction(self, course: float | None) -> float:
        """Return the heading change (rad) since the run started: the gyro's, else the COG's."""
        if self.gyro:
            return self.turn
        if course is not None and self.course0 is not None:
            return float(ssa(course - self.course0))
        return 0.0


class StuckLog:
    """The stuck-log test (see the module notes)."""

    __slots__ = ('value', 't0', 'start', 'current0', 'sigma0', 'stuck', 'change')

    def __init__(self) -> None:
        self.value: float | None = None
        self.t0 = 0.0
        #: The fixes' velocity through the water over the run's first window (N, E m/s).
        self.start: tuple[float, float] | None = None
        self.current0 = (0.0, 0.0)
        self.sigma0 = 0.0
        self.stuck = False
        #: How far the fixes' speed through the water moved while the log held (m/s).
        self.change = 0.0

    def reading(self, t: float, surge: float, track: GnssTrack, current: Sequence[float],
                current_sigma: float = 0.0) -> str | None:
        """
        Take the log's surge reading, m/s, at ``t`` (s); return why it is stuck, or None.

        ``track`` the fixes; ``current`` the current estimated now (N, E m/s; zeros over
        ground) and ``current_sigma`` its σ (m/s, per axis). The fixes' velocity is compared
        over two windows of :data:`~.config.FROZEN_LOG_WINDOW` within the run (the first and
        the last), so that its lag never makes a braking boat's log look stuck. An error δc of
        the current changes the speed through the water |V − c| by up to |u₁ − u₀|·|δc| as its
        direction turns from u₀ to u₁: the threshold grows by 3σ_c of that, so that a turn in
        a current not yet known is no stuck log.
        """
        if self.value is None or abs(surge - self.value) > FROZEN_LOG_TOLERANCE:
            self.value, self.t0, self.start, self.stuck = surge, t, None, False
            self.current0 = (float(current[0]), float(current[1]))
            self.sigma0 = current_sigma
            return None
        if self.stuck:
            return 'log stuck'
        if self.start is None:
            if t < self.t0 + FROZEN_LOG_WINDOW:
                return None
            self.start = self._through_water(track.velocity(self.t0 + FROZEN_LOG_WINDOW))
            return None
        if t < self.t0 + 2.0 * FROZEN_LOG_WINDOW:
            return None
        now = self._through_water(track.velocity(t))
        if now is None:
            return None
        s0, s1 = math.hypot(*self.start), math.hypot(*now)
        turn = 0.0
        if s0 > 0.0 and s1 > 0.0:
            turn = math.hypot(now[0] / s1 - self.start[0] / s0, now[1] / s1 - self.start[1] / s0)
        if abs(s1 - s0) >= FROZEN_LOG_SPEED_CHANGE + 3.0 * self.sigma0 * turn:
            self.stuck, self.change = True, abs(s1 - s0)
            return (f"log stuck at {self.value:.2f} m/s while the fixes' speed through the "
                    f'water went from {s0:.2f} to {s1:.2f} m/s')
        return None

    def _through_water(self, v_gnss: tuple[float, float] | None) -> tuple[float, float] | None:
        if v_gnss is None:
            return None
        return v_gnss[0] - self.current0[0], v_gnss[1] - self.current0[1]
