"""
The node's services: robot_localization's geodesy services, reset and pause, as r_l offers them.

* ``fromLL`` (``robot_localization/srv/FromLL``): a geodetic point (deg, m) to the map point
  (ENU about the origin, m), as navsat_transform answers nav2's GPS waypoint follower;
* ``toLL`` (``robot_localization/srv/ToLL``): the inverse;
* ``datum`` (``robot_localization/srv/SetDatum``, navsat_transform's name; also ``setDatum``):
  sets the parameter ``origin`` to the pose's latitude, longitude and altitude, through the
  node's own parameter path (validated, the position re-expressed, ``origin`` re-published).
  The pose's orientation is not used: the map is ENU about the origin, never rotated;
* ``~/reset`` (``std_srvs/Trigger``): re-initialises the estimate, keeping the origin;
* ``~/enable`` (``std_srvs/SetBool``) and ``toggle`` (``robot_localization/srv/
  ToggleFilterProcessing``, r_l's filter name): pause and resume fusion. While paused every
  input is counted as ``paused`` and nothing is fused or published; ``/diagnostics`` says
  ``paused``.

``fromLL`` and ``toLL`` are the estimator's own projection (:mod:`vessel_kinematics.estimation.
mapframe`, ``projection`` tangent or flat), exact to the float. Before the origin is known they
answer NaN, and so they do for a point that is none: not finite, a latitude beyond ±90°, a
longitude beyond -180..360°, or a height or map coordinate beyond :data:`MAX_DISTANCE`. A
datum that is no such point is refused. A service whose type cannot be imported is not
offered: one line at start-up names the missing ones and the package to install.
"""

from __future__ import annotations

import importlib
import math
from typing import Any, Callable

from rclpy.node import Node
from rclpy.parameter import Parameter
from vessel_kinematics.estimation import mapframe

__all__ = ['MAX_DISTANCE', 'NodeServices', 'SERVICES']

#: The largest height or map coordinate (m) a geodesy service converts: half a meridian.
MAX_DISTANCE = 2.0e7

#: The services, by name: their type (``package/srv/Name``) and the handler's attribute.
SERVICES: dict[str, tuple[str, str]] = {
    'fromLL': ('robot_localization/srv/FromLL', '_from_ll'),
    'toLL': ('robot_localization/srv/ToLL', '_to_ll'),
    'datum': ('robot_localization/srv/SetDatum', '_set_datum'),
    'setDatum': ('robot_localization/srv/SetDatum', '_set_datum'),
    'toggle': ('robot_localization/srv/ToggleFilterProcessing', '_toggle'),
    '~/reset': ('std_srvs/srv/Trigger', '_reset'),
    '~/enable': ('std_srvs/srv/SetBool', '_enable'),
}

#: The apt package of each interface package (the start-up line names it).
_APT = {'robot_localization': 'ros-jazzy-robot-localization', 'std_srvs': 'ros-jazzy-std-srvs'}


def _point_problem(lat: float, lon: float, height: float) -> str | None:
    """Return why a geodetic point (deg, deg, m) is none, or None."""
    if not (abs(lat) <= 90.0 and -180.0 <= lon <= 360.0 and abs(height) <= MAX_DISTANCE):
        return f'({lat:g}, {lon:g}, {height:g}) is not a latitude, longitude and height'
    return None


def _service_class(srv_type: str) -> type:
    package, kind, name = srv_type.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)


class NodeServices:
    """
    The services of :data:`SERVICES`, served for ``navigator`` (the node: its pipeline).

    ``guard(name, function)`` wraps each handler so that nothing it raises leaves it (a
    handler that failed answers the default response); ``send`` publishes emissions.
    """

    def __init__(self, node: Node, navigator: Any,
                 guard: Callable[[str, Callable[..., None]], Callable[..., None]],
                 log: Any) -> None:
        self._node = node
        self._navigator = navigator
        self._log = log
        self.servers: dict[str, Any] = {}
        missing: dict[str, list[str]] = {}
        for name, (srv_type, handler) in SERVICES.items():
            try:
                cls = _service_class(srv_type)
            except (ImportError, AttributeError):
                missing.setdefault(srv_type.split('/')[0], []).append(name)
                continue
            self.servers[name] = node.create_service(
                cls, name, self._guarded(guard, name, getattr(self, handler)))
        if missing:
            self._log.warning('services not offered (interface packages missing): ' + '; '.join(
                f'{", ".join(names)} (install {_APT.get(package, package)})'
                for package, names in missing.items()))

    @staticmethod
    def _guarded(guard: Callable[[str, Callable[..., None]], Callable[..., None]], name: str,
                 handler: Callable[[Any, Any], Any]) -> Callable[[Any, Any], Any]:
        """Return the handler answering ``response`` even when it raised (counted by guard)."""
        def run(request: Any, response: Any) -> Any:
            guard(f'service {name}', handler)(request, response)
            return response
        return run

    @property
    def _pipeline(self) -> Any:
        return self._navigator.pipeline

    def _origin(self) -> tuple[float, float, float] | None:
        return self._pipeline.estimator.origin

    # --- robot_localization's ---------------------------------------------------------------

    def _geodesy(self, name: str, convert: Callable[..., tuple[float, float, float]],
                 problem: str | None, *args: float) -> tuple[float, float, float]:
        """Return ``convert(origin, projection, *args)``, or NaNs (said) before the origin."""
        origin = self._origin()
        if origin is None or problem is not None:
            why = 'no origin yet' if problem is None else problem
            self._log.throttled(f'service/{name}', f'{name}: {why}: answered NaN')
            return math.nan, math.nan, math.nan
        return convert(origin, self._pipeline.params.projection, *args)

    def _from_ll(self, request: Any, response: Any) -> None:
        """FromLL: ``ll_point`` (deg, m) to ``map_point`` (map ENU, m); NaN without origin."""
        p = request.ll_point
        out = response.map_point
        out.x, out.y, out.z = self._geodesy('fromLL', mapframe.map_enu, _point_problem(
            p.latitude, p.longitude, p.altitude), p.latitude, p.longitude, p.altitude)

    def _to_ll(self, request: Any, response: Any) -> None:
        """ToLL: ``map_point`` (map ENU, m) to ``ll_point`` (deg, m); NaN without origin."""
        p = request.map_point
        out = response.ll_point
        far = not all(math.isfinite(c) and abs(c) <= MAX_DISTANCE for c in (p.x, p.y, p.z))
        out.latitude, out.longitude, out.altitude = self._geodesy(
            'toLL', mapframe.geodetic_of_map_enu,
            f'map point ({p.x:g}, {p.y:g}, {p.z:g}) m is not on the earth' if far else None,
            p.x, p.y, p.z)

    def _set_datum(self, request: Any, response: Any) -> None:
        """SetDatum: the parameter ``origin`` := the pose's position (its orientation unused)."""
        position = request.geo_pose.position
        value = [float(position.latitude), float(position.longitude), float(position.altitude)]
        problem = _point_problem(*value)
        if problem is not None:
            self._log.warning(f'datum refused: {problem}')
            return
        result = self._node.set_parameters(
            [Parameter('origin', Parameter.Type.DOUBLE_ARRAY, value)])[0]
        if result.successful:
            self._log.info(f'datum set: origin {value}')
        else:
            self._log.warning(f'datum refused: {result.reason}')

    def _toggle(self, request: Any, response: Any) -> None:
        """ToggleFilterProcessing: ``on`` resumes, else pauses; ``status`` is the new state."""
        response.status = self._set_enabled(bool(request.on))

    # --- the navigator's --------------------------------------------------------------------

    def _reset(self, request: Any, response: Any) -> None:
        """Trigger: re-initialise the estimate, keep the origin."""
        self._pipeline.reset()
        response.success = True
        response.message = 'estimate re-initialised, origin kept'
        self._log.info('reset: estimate re-initialised, origin kept')

    def _enable(self, request: Any, response: Any) -> None:
        """SetBool: true resumes fusion, false pauses it."""
        enabled = self._set_enabled(bool(request.data))
        response.success = True
        response.message = 'fusion enabled' if enabled else 'fusion paused'

    def _set_enabled(self, enabled: bool) -> bool:
        """Pause (False) or resume (True) fusion; say it when it changes; return the state."""
        pipeline = self._pipeline
        if pipeline.paused == enabled:
            pipeline.paused = not enabled
            self._log.info('fusion enabled' if enabled else
                           'fusion paused: inputs counted as paused, no outputs')
        return not pipeline.paused
