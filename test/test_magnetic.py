"""
Tests of the magnetic declination (WMM2025 through NOAA's wmm-calculator) and of decimal_year.

The reference is NOAA's own: the 100 official WMM2025 test values published with the model's
coefficients (WMM2025_TestValues.txt; the same table ships in the source repository of the
wmm-calculator package as WMM2025_FINAL_TEST_VALUES.txt), declination rounded to 0.01 deg.
"""

from __future__ import annotations

import calendar
import datetime
import math

from geomaglib.util import calc_dec_year
from hypothesis import given, strategies as st
import pytest
from vessel_kinematics.estimation import magnetic
from vessel_kinematics.estimation.magnetic import (decimal_year, declination,
                                                   declination_uncertainty)

#: NOAA's WMM2025 test values, the first five fields: decimal year, height above the WGS-84
#: ellipsoid (km), geodetic latitude and longitude (deg), declination (deg).
WMM2025_TEST_VALUES = """
2025.000   28   89  -121   -99.77
2025.000   48   80   -96   -29.91
2025.000   54   82    87    54.89
2025.000   65   43    93     0.50
2025.000   51  -33   109    -5.49
2025.000   39  -59    -8   -15.75
2025.000    3  -50  -103    27.96
2025.000   94  -29  -110    15.74
2025.000   66   14   143    -0.19
2025.000   18    0    21     1.29
2025.500    6  -36  -137    20.28
2025.500   63   26    81     0.51
2025.500   69   38  -144    12.93
2025.500   50  -70  -133    57.21
2025.500    8  -52   -75    14.91
2025.500    8  -66    17   -33.14
2025.500   22  -37   140     9.28
2025.500   40  -12  -129    10.76
2025.500   44   33  -118    11.10
2025.500   50  -81   -67    28.13
2026.000   74  -57     3   -22.51
2026.000   46  -24  -122    14.01
2026.000   69   23    63     1.17
2026.000   33   -3  -147     9.71
2026.000   47  -72   -22    -6.32
2026.000   62  -14    99    -1.43
2026.000   83   86   -46   -30.61
2026.000   82  -64    87   -81.74
2026.000   34  -19    43   -14.98
2026.000   56  -81    40   -59.77
2026.500   14    0    80    -3.10
2026.500   12  -82   -68    29.79
2026.500   44  -46   -42   -11.36
2026.500   43   17    52     1.19
2026.500   64   10    78    -1.53
2026.500   12   33  -145    11.96
2026.500   12  -79   115  -137.58
2026.500   14  -33  -114    18.12
2026.500   19   29    66     2.24
2026.500   86  -11   167    10.24
2027.000   37  -66    -5   -17.22
2027.000   67   72  -115    13.73
2027.000   44   22   174     6.46
2027.000   54   54   178     0.63
2027.000   57  -43    50   -48.27
2027.000   44  -43  -111    24.31
2027.000   12  -63   178    57.87
2027.000   38   27  -169     8.48
2027.000   61   59   -77   -16.48
2027.000   67  -47   -32   -13.52
2027.500    8   62    53    19.39
2027.500   77  -68    -7   -16.19
2027.500   98   -5   159     7.79
2027.500   34  -29  -107    15.64
2027.500   60   27    65     1.85
2027.500   73  -72    95  -102.64
2027.500   96  -46   -85    17.93
2027.500    0  -13   -59   -17.49
2027.500   16   66  -178     0.37
2027.500   72  -87    38   -65.44
2028.000   49   20   167     5.10
2028.000   71    5   -13    -6.47
2028.000   95   14    65    -0.51
2028.000   86  -85   -79    41.09
2028.000   30  -36   -64    -4.65
2028.000   75   79   125   -18.59
2028.000   21    6   -32   -14.34
2028.000    1  -76   -75    29.87
2028.000   45  -46   -41   -11.68
2028.000   11  -22   -21   -23.24
2028.500   28   54  -120    15.43
2028.500   68  -58   156    41.57
2028.500   39  -65   -88    29.45
2028.500   27  -23    81   -13.27
2028.500   11   34     0     1.57
2028.500   72  -62    65   -67.87
2028.500   55   86    70    67.64
2028.500   59   32   163     0.15
2028.500   65   48   148    -9.55
2028.500   95   30    28     4.56
2029.000   95  -60   -59     8.58
2029.000   95  -70    42   -55.06
2029.000   50   87  -154   -73.48
2029.000   58   32    19     4.11
2029.000   57   34   -13    -1.89
2029.000   38  -76    49   -64.28
2029.000   49  -50  -179    32.11
2029.000   90  -55  -171    38.65
2029.000   41   42   -19    -4.13
2029.000   19   46   -22    -5.65
2029.500   31   13  -132     9.04
2029.500   93   -2   158     7.09
2029.500   51  -76    40   -56.34
2029.500   64   22  -132    10.23
2029.500   26  -65    55   -63.48
2029.500   66  -21    32   -14.63
2029.500   18    9  -172     9.24
2029.500   63   88    26    36.52
2029.500   33   17     5     0.89
2029.500   77  -18   138     4.45
"""

BOSTON = (math.radians(42.36), math.radians(-71.06), 0.0)
SEATTLE = (math.radians(47.6205), math.radians(-122.3493), 0.0)


def _rows() -> list[tuple[float, ...]]:
    return [tuple(float(v) for v in line.split())
            for line in WMM2025_TEST_VALUES.strip().splitlines()]


def test_noaa_wmm2025_test_values() -> None:
    rows = _rows()
    assert len(rows) == 100
    worst = 0.0
    for year, height_km, lat, lon, expected in rows:
        got = math.degrees(declination(math.radians(lat), math.radians(lon),
                                       height_km * 1000.0, year))
        worst = max(worst, abs(got - expected))
    # The table is rounded to 0.01 deg: agreement to the rounding.
    assert worst <= 0.0051


def test_well_known_values_and_sign() -> None:
    # Boston: about 14 deg west (negative) in 2025; Seattle about 15 deg east (positive).
    assert math.degrees(declination(*BOSTON, 2025.5)) == pytest.approx(-14.0, abs=0.3)
    assert math.degrees(declination(*SEATTLE, datetime.date(2025, 4, 2))) == \
        pytest.approx(15.07, abs=0.05)
    # It changes slowly: Boston moves by a fraction of a degree over the model's life.
    drift = declination(*BOSTON, 2029.9) - declination(*BOSTON, 2025.0)
    assert 0.0 < abs(math.degrees(drift)) < 1.0


def test_uncertainty_follows_the_wmm2025_error_model() -> None:
    boston = math.degrees(declination_uncertainty(*BOSTON, 2025.5))
    assert 0.3 < boston < 0.5
    # One degree off the geographic pole, near the magnetic one: H = 1504 nT (NOAA's table).
    pole = (math.radians(89.0), math.radians(-121.0), 28_000.0)
    expected = math.hypot(0.26, 5417.0 / 1504.0)
    assert math.degrees(declination_uncertainty(*pole, 2025.0)) == \
        pytest.approx(expected, rel=1e-3)
    assert math.degrees(declination(*pole, 2025.0)) == pytest.approx(-99.77, abs=0.0051)


def test_date_forms_agree() -> None:
    instant = datetime.datetime(2026, 3, 14, 6, 30, tzinfo=datetime.timezone.utc)
    stamp_ns = calendar.timegm(instant.timetuple()) * 1_000_000_000
    year = decimal_year(stamp_ns)
    expected = declination(*BOSTON, year)
    assert declination(*BOSTON, instant) == expected
    assert declination(*BOSTON, instant.replace(tzinfo=None)) == expected       # naive: UTC
    oslo = datetime.timezone(datetime.timedelta(hours=1))
    assert declination(*BOSTON, instant.astimezone(oslo)) == expected
    midnight = declination(*BOSTON, decimal_year(calendar.timegm((2026, 3, 14, 0, 0, 0))
                                                 * 1_000_000_000))
    assert declination(*BOSTON, datetime.date(2026, 3, 14)) == midnight


def test_longitude_wraps_and_height_counts() -> None:
    lat, lon, _ = BOSTON
    assert declination(lat, lon + 2 * math.pi, 0.0, 2026.0) == \
        pytest.approx(declination(lat, lon, 0.0, 2026.0), abs=1e-12)
    assert declination(lat, lon, 100_000.0, 2026.0) != declination(lat, lon, 0.0, 2026.0)


@pytest.mark.parametrize('when', [2024.999, 2030.0, 2035.5, datetime.date(2024, 12, 31),
                                  datetime.date(2030, 1, 1), 1_750_000_000_000_000_000])
def test_outside_the_model_life_is_refused(when: object) -> None:
    with pytest.raises(ValueError, match=r'valid from 2025\.0 up to 2030\.0'):
        declination(*BOSTON, when)
    with pytest.raises(ValueError, match='WMM2025'):
        declination_uncertainty(*BOSTON, when)


@pytest.mark.parametrize('position', [(math.nan, 0.0, 0.0), (0.0, math.inf, 0.0),
                                      (0.0, 0.0, math.nan), (1.6, 0.0, 0.0),
                                      (0.0, 0.0, -5000.0), (0.0, 0.0, 9e5)])
def test_bad_positions_are_refused(position: tuple[float, float, float]) -> None:
    with pytest.raises(ValueError):
        declination(*position, 2026.0)


def test_bad_date_types_are_refused() -> None:
    for when in ('2026-01-01', None, True):
        with pytest.raises(TypeError):
            declination(*BOSTON, when)


def test_decimal_year_known_instants() -> None:
    ns = 1_000_000_000
    assert decimal_year(calendar.timegm((2025, 1, 1, 0, 0, 0)) * ns) == 2025.0
    assert decimal_year(calendar.timegm((2025, 7, 2, 12, 0, 0)) * ns) == 2025.5
    assert decimal_year(calendar.timegm((2028, 12, 31, 0, 0, 0)) * ns) == \
        pytest.approx(2028 + 365 / 366, abs=1e-12)
    # The simulator's voyage starts 2024-06-01T12:00Z, outside WMM2025.
    assert decimal_year(1_717_243_200 * ns) == pytest.approx(2024 + (152.5 / 366), abs=1e-12)
    # One second before the new year (a float resolves about 7 us here).
    assert decimal_year((calendar.timegm((2026, 1, 1, 0, 0, 0)) - 1) * ns) < 2026.0


@given(st.datetimes(min_value=datetime.datetime(1970, 1, 1),
                    max_value=datetime.datetime(2100, 12, 31, 23, 59, 59)))
def test_decimal_year_matches_noaas_convention(moment: datetime.datetime) -> None:
    stamp_ns = calendar.timegm(moment.timetuple()) * 1_000_000_000 + moment.microsecond * 1000
    year = decimal_year(stamp_ns)
    assert moment.year <= year <= moment.year + 1      # + 1 only within float resolution
    reference = calc_dec_year(moment.year, moment.month, moment.day, moment.hour,
                              moment.minute, moment.second + moment.microsecond * 1e-6)
    assert year == pytest.approx(reference, abs=1e-11)


def test_module_exports() -> None:
    assert set(magnetic.__all__) == {'WMM_VALID_FROM', 'WMM_VALID_UNTIL', 'declination',
                                     'declination_at_stamp', 'declination_uncertainty',
                                     'decimal_year'}
    assert (magnetic.WMM_VALID_FROM, magnetic.WMM_VALID_UNTIL) == (2025.0, 2030.0)


def test_declination_at_stamp_is_the_declination_at_its_date() -> None:
    stamp_ns = 1_785_732_421_302_000_128            # the motorboat bag, 2026-08-03
    lat, lon = math.radians(34.40), math.radians(133.56)
    assert magnetic.declination_at_stamp(lat, lon, 0.0, stamp_ns) == magnetic.declination(
        lat, lon, 0.0, decimal_year(stamp_ns))
    with pytest.raises(ValueError):
        magnetic.declination_at_stamp(lat, lon, 0.0, 1_534_758_457 * 10 ** 9)   # 2018
