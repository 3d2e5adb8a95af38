"""Parameter ranges and read-only metadata: table-driven good and bad values, one-line reasons."""

from __future__ import annotations

import math
from typing import Any

import pytest
from vessel_kinematics.ros.params import NavigatorParams, ParameterError, PARAMETERS

NAN = math.nan
BY_NAME = {p.name: p for p in PARAMETERS}

GOOD: list[tuple[str, Any]] = [
    ('publish_rate', 0.0), ('publish_rate', 0.1), ('publish_rate', 10), ('publish_rate', 1000.0),
    ('gnss.antenna_position', [-3.0, 0.0, 5.0]), ('gnss.antenna_position', [1000.0, -1000, 0]),
    ('origin', [NAN, NAN, NAN]), ('origin', [59.9, 10.7, -12000.0]),
    ('origin', [-90.0, 359.0, 50000.0]), ('origin', [1.0, 2.0, NAN]),
    ('gnss.default_sigma', 1e-3), ('gnss.default_sigma', 1e4),
    ('velocity.default_sigma', 1e-4), ('velocity.default_sigma', 100.0),
    ('gnss.gate_sigma', 0.0), ('gnss.gate_sigma', 1000.0),
    ('max_gap', 1e-2), ('max_gap', 3600.0), ('history_length', 0.0), ('history_length', 10.0),
    ('future_tolerance', 0.0), ('fix.time_offset', -18.0),
    ('imu.mounting_rpy', [math.pi, -math.pi / 2, 2 * math.pi]), ('imu.yaw_offset', -2 * math.pi),
    ('map_frame', 'world'), ('base_frame', 'robot1/base_link'), ('odom_frame', '_odom2'),
    ('earth_frame', 'EARTH'),
]

BAD: list[tuple[str, Any, str]] = [
    ('publish_rate', 1e-300, '0 (publish on each update) or in [0.1'),
    ('publish_rate', 1e-10, 'or in [0.1'), ('publish_rate', 0.099, 'or in [0.1'),
    ('publish_rate', 1000.001, 'must be in'), ('publish_rate', -1.0, 'must be in'),
    ('publish_rate', NAN, 'finite'), ('publish_rate', math.inf, 'finite'),
    ('gnss.antenna_position', [1e200, 0.0, 0.0], '[-1000, 1000]'),
    ('gnss.antenna_position', [0.0, -1000.5, 0.0], '[-1000, 1000]'),
    ('origin', [59.9, 10.7, 1e20], 'height'), ('origin', [59.9, 10.7, -12001.0], 'height'),
    ('origin', [95.0, 10.7, 0.0], 'latitude'), ('origin', [10.0, 361.0, 0.0], 'longitude'),
    ('gnss.default_sigma', 0.0, 'must be in'), ('gnss.default_sigma', 1e5, 'must be in'),
    ('velocity.default_sigma', 0.0, 'must be in'), ('velocity.default_sigma', 101.0, 'must be in'),
    ('gnss.gate_sigma', -1.0, 'must be in'), ('gnss.gate_sigma', 1e4, 'must be in'),
    ('max_gap', 0.0, 'must be in'), ('max_gap', 1e5, 'must be in'),
    ('history_length', 11.0, 'must be in'), ('future_tolerance', -1.0, 'must be in'),
    ('imu.mounting_rpy', [0.0, 0.0, 7.0], 'each component'),
    ('map_frame', 'map\n', 'frame id'), ('map_frame', 'ma\x07p', 'frame id'),
    ('odom_frame', '/odom', 'frame id'), ('base_frame', 'base link', 'frame id'),
    ('base_frame', 'base_link/', 'frame id'), ('base_frame', 'a//b', 'frame id'),
    ('earth_frame', '1earth', 'frame id'), ('earth_frame', '', 'frame id'),
    ('earth_frame', 'é', 'frame id'), ('map_frame', 'm' * 257, 'frame id'),
    ('map_frame', 3, 'frame id'),
]


@pytest.mark.parametrize('name, value', GOOD)
def test_good_values(name: str, value: Any) -> None:
    params = NavigatorParams.from_flat({name: value})
    got = params.to_flat()[name]
    if isinstance(value, list):
        assert got == pytest.approx(value, nan_ok=True)
    else:
        assert got == value


@pytest.mark.parametrize('name, value, reason', BAD)
def test_bad_values_one_line_reason(name: str, value: Any, reason: str) -> None:
    with pytest.raises(ParameterError) as caught:
        NavigatorParams.from_flat({name: value})
    message = str(caught.value)
    assert caught.value.name == name and reason in message, message
    assert '\n' not in message.replace(repr(value), '')


def test_every_numeric_parameter_has_a_range_that_its_check_enforces() -> None:
    for p in PARAMETERS:
        numeric = isinstance(p.default, float) or (
            isinstance(p.default, list) and p.name != 'origin'
            and all(isinstance(v, float) for v in p.default))
        if not numeric:
            assert p.low is None and p.high is None, p.name
            continue
        assert p.low is not None and p.high is not None and p.low < p.high, p.name

        def value(x: float, p: Any = p) -> Any:
            return [x, x, x] if isinstance(p.default, list) else x

        # stale_warn must not exceed stale_error: each is tested with the other out of the way.
        extra = {'diagnostics.stale_warn': {'diagnostics.stale_error': 3600.0},
                 'diagnostics.stale_error': {'diagnostics.stale_warn': 0.01}}.get(p.name, {})
        NavigatorParams.from_flat({p.name: value(p.high), **extra})
        if p.name != 'publish_rate':  # 0 or [0.1, high]: the low end is 0 itself
            NavigatorParams.from_flat({p.name: value(p.low), **extra})
        for outside in (math.nextafter(p.high, math.inf), math.nextafter(p.low, -math.inf)):
            with pytest.raises(ParameterError):
                NavigatorParams.from_flat({p.name: value(outside), **extra})


def test_read_only_metadata() -> None:
    read_only = {p.name for p in PARAMETERS if p.read_only}
    assert read_only == {'map_frame', 'odom_frame', 'base_frame', 'earth_frame', 'projection',
                         'motion'}
    # The ones that must change at run time (issue 8) stay writable.
    for name in ('velocity.source', 'sensor_qos', 'publish_rate', 'origin'):
        assert not BY_NAME[name].read_only
