"""
The filter's state vector, by name: which states exist and where they sit.

Like robot_localization's ``StateMemberX`` indices, but derived from the configuration: a
surface vessel with a speed log has a different state than an underwater vehicle with a
bottom-tracking DVL. Every other module addresses the state through a :class:`StateLayout`,
never through a bare index.

The blocks, in order (d = 2 for the planar motions, 3 for ``free``):

=========  ====  ==================================================================
``p``      d     NED position of the base about the origin (m): N, E (, D)
``l``      d     the local (odom) position (m): integrated like ``p``, never corrected
                 (a Schmidt consider state: its gain is zero, its covariance only grows)
``v``      d     velocity (m/s, physical units: a log reads k times it). Planar: [u, v] along
                 and across the heading, horizontal (through water: [u_r, b], sway
                 v_r = tan(λ)·u_r + b·√(u_r² + U₀²) + κ·r, b a drift ratio); ``free``: body
                 [u, v, w].
                 Over ground, or through the water (``water``)
``a``      1|d   the acceleration of the velocity (m/s²): of the surge, or of every axis
                 with no velocity sensor (``isotropic``), a Singer process (:mod:`.model`)
``c``      2     the ocean current N, E (m/s; water only)
``k``      1     the velocity sensor's scale factor, reading / truth (water only)
``lam``    1     the leeway angle λ (rad; planar water only)
``kap``    1     the turning drift κ (m/rad; planar water only): a hull turning at r
                 slides sideways through the water at κ·r (its drift angle in a turn)
``dpsi``   1     the IMU heading offset δψ (rad; when estimated)
=========  ====  ==================================================================
"""

from __future__ import annotations

from dataclasses import dataclass

from vessel_kinematics.estimation.config import (FilterConfig, INITIAL_VELOCITY_SIGMA,
                                                 SWAY_RATIO)

__all__ = ['StateLayout']


@dataclass(frozen=True)
class StateLayout:
    """Named slices and indices of the state vector (None where a state does not exist)."""

    dim: int
    p: slice
    l: slice  # noqa: E741 - Fossen-style short block names, documented above
    v: slice
    a: slice
    c: slice | None
    k: int | None
    lam: int | None
    kap: int | None
    dpsi: int | None
    size: int
    #: No velocity sensor: the velocity is the vessel's over ground, seen only through the
    #: fixes, with no preferred direction (both axes the surge's prior).
    isotropic: bool = False

    @property
    def water(self) -> bool:
        """Return True for a velocity state through the water, with the current estimated."""
        return self.c is not None

    @property
    def velocity_prior(self) -> tuple[float, ...]:
        """
        Return the σ of each velocity state before any measurement, in its own unit.

        :data:`~.config.INITIAL_VELOCITY_SIGMA` (m/s) for a velocity; the drift ratio b
        (planar water) is a ratio, not a speed: its stationary σ (:data:`~.config.SWAY_RATIO`).
        """
        sigmas = [INITIAL_VELOCITY_SIGMA] * self.dim
        if self.water and self.horizontal:
            sigmas[1] = SWAY_RATIO.sigma
        return tuple(sigmas)

    @property
    def accelerated(self) -> list[tuple[int, int]]:
        """Return (velocity index, its acceleration's index) of every accelerated axis."""
        return [(self.v.start + i, self.a.start + i) for i in range(self.a.stop - self.a.start)]

    @property
    def horizontal(self) -> bool:
        """Return True for a planar state (2-D position and velocity)."""
        return self.dim == 2

    @classmethod
    def of(cls, config: FilterConfig) -> StateLayout:
        """Return the layout a configuration needs."""
        d = 2 if config.horizontal else 3
        n = 0

        def block(size: int) -> slice:
            nonlocal n
            s = slice(n, n + size)
            n += size
            return s

        def index() -> int:
            nonlocal n
            n += 1
            return n - 1

        p, loc, v = block(d), block(d), block(d)
        isotropic = not config.velocity_input
        a = block(d if isotropic else 1)
        water = config.water and config.velocity_input
        c = block(2) if water else None
        k = index() if water and config.estimate_scale else None
        # Leeway and a heading offset both rotate the velocity through the water: with the
        # heading offset estimated they cannot be told apart, and the offset takes it all.
        lam = (index() if water and d == 2 and config.estimate_leeway
               and not config.estimate_heading_offset else None)
        kap = index() if water and d == 2 else None
        dpsi = index() if config.estimate_heading_offset else None
        return cls(dim=d, p=p, l=loc, v=v, a=a, c=c, k=k, lam=lam, kap=kap, dpsi=dpsi, size=n,
                   isotropic=isotropic)

    def names(self) -> list[str]:
        """Return a name for each element of the state vector, in order (for messages)."""
        axes = ('n', 'e', 'd')
        vel = (('u', 'v', 'w') if self.dim == 3 else
               ('u', 'b') if self.water else ('u', 'v'))
        out = [f'p_{a}' for a in axes[:self.dim]] + [f'l_{a}' for a in axes[:self.dim]]
        out += list(vel)
        out += [f'a_{name}' for name in vel[:self.a.stop - self.a.start]]
        if self.c is not None:
            out += ['c_n', 'c_e']
        for name in ('k', 'lam', 'kap', 'dpsi'):
            if getattr(self, name) is not None:
                out.append(name)
        return out
