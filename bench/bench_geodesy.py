"""
Benchmark vessel_kinematics.core.geodesy against pyproj (PROJ) and pymap3d: accuracy and speed.

Run from the repository root: ``python bench/bench_geodesy.py``. Prints, asserts nothing.

1. Accuracy of ecef2llh o llh2ecef on a grid that includes the exact poles, 5000 km below
   the surface and 1e8 m above it: the error of a returned (lat, lon, h) is the distance (nm)
   between its exact (50-digit mpmath) ECEF image and the exact image of the input, divided by
   max(1, r / a) (target <= 10 nm). The same ECEF points go to pymap3d and pyproj.
2. Vectorised throughput on 1e6 points, llh2ecef and ecef2llh vs a pyproj Transformer
   (EPSG:4979 <-> EPSG:4978), in the same run: time (ms) and ratio pyproj / ours.
3. Single-point calls (what a node does per message): microseconds per call and ratio. The
   per-message functions (llh2ned, ned2llh, llh2flat, flat2llh) keep a math body beside the
   numpy one; the numpy body on a one-element batch is printed next to them, which is what
   a call would cost without it (issue 9). ``--scalar`` runs only this part.
"""

from __future__ import annotations

import math
from pathlib import Path
import sys
import time
import timeit
import warnings

import mpmath
import numpy as np
import pymap3d
import pyproj

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from vessel_kinematics.core import geodesy as geo  # noqa: E402

MP = mpmath.MPContext()
MP.dps = 40
A_MP = MP.mpf(6378137)
F_MP = 1 / MP.mpf('298.257223563')
E2_MP = F_MP * (2 - F_MP)


def mp_llh2ecef(lat: float, lon: float, h: float) -> tuple:
    """Return the exact ECEF image (mpf) of double (lat, lon, h) in rad, rad, m."""
    lat, lon, h = MP.mpf(lat), MP.mpf(lon), MP.mpf(h)
    n = A_MP / MP.sqrt(1 - E2_MP * MP.sin(lat) ** 2)
    return ((n + h) * MP.cos(lat) * MP.cos(lon), (n + h) * MP.cos(lat) * MP.sin(lon),
            (n * (1 - E2_MP) + h) * MP.sin(lat))


def distance(a: tuple, b: tuple) -> float:
    """Return the Euclidean distance of two mpf triples as a float (m)."""
    return float(MP.sqrt(sum((x - y) ** 2 for x, y in zip(a, b))))


def accuracy() -> None:
    """Print the round-trip error on the grid, ours next to pymap3d and pyproj."""
    lat_deg = np.concatenate(([-90.0, -89.999999, 90.0, 89.999999, 0.0],
                              np.linspace(-85.0, 85.0, 18)))
    lon_deg = np.array([-179.999, -100.0, 0.0, 45.0, 180.0])
    heights = np.array([-5e6, -3e6, -1e6, -1e5, -1e4, 0.0, 1e3, 1e5, 1e6, 1e7, 3.6e7, 1e8])
    lat, lon, h = (g.ravel() for g in np.meshgrid(np.radians(lat_deg), np.radians(lon_deg),
                                                  heights, indexing='ij'))
    p = geo.llh2ecef(lat, lon, h)
    scale = np.maximum(1.0, np.linalg.norm(p, axis=-1) / geo.WGS84_A)
    exact_in = [mp_llh2ecef(*v) for v in zip(lat.tolist(), lon.tolist(), h.tolist())]
    p_mp = [tuple(MP.mpf(c) for c in row) for row in p.tolist()]

    inverse = pyproj.Transformer.from_crs('EPSG:4978', 'EPSG:4979', always_xy=True)
    lon_p, lat_p, h_p = inverse.transform(p[:, 0], p[:, 1], p[:, 2])
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        lat_m, lon_m, h_m = pymap3d.ecef2geodetic(p[:, 0], p[:, 1], p[:, 2], deg=False)
        lat_f, lon_f, h_f = geo.ecef2llh_fossen(p)
    results = {
        'vessel_kinematics.ecef2llh': geo.ecef2llh(p),
        'vessel_kinematics.ecef2llh_fossen': (lat_f, lon_f, h_f),
        'pymap3d.ecef2geodetic': (np.asarray(lat_m), np.asarray(lon_m), np.asarray(h_m)),
        'pyproj (EPSG:4978->4979)': (np.radians(lat_p), np.radians(lon_p), np.asarray(h_p)),
    }
    print(f'1. ecef2llh o llh2ecef round trip on {lat.size} points: latitudes incl. exact poles,'
          f' h from {heights.min():.0e} to {heights.max():.0e} m')
    print('   error = |F(llh_out) - F(llh_in)| / max(1, r/a), F exact (mpmath); target 10 nm')
    header = f'   {"implementation":36s} {"max nm":>12s} {"rms nm":>10s}   worst point'
    print(header)
    for name, (la, lo, hh) in results.items():
        err = np.array([distance(mp_llh2ecef(*v), e) if np.isfinite(v).all() else math.inf
                        for v, e in zip(zip(la.tolist(), lo.tolist(), hh.tolist()), exact_in)])
        err_nm = err / scale * 1e9
        worst = int(np.argmax(err_nm))
        rms = math.sqrt(float(np.mean(np.where(np.isfinite(err_nm), err_nm, 0.0) ** 2)))
        print(f'   {name:36s} {err_nm[worst]:12.4g} {rms:10.3g}   lat {lat_deg_of(lat[worst])}'
              f' deg, h {h[worst]:.0e} m')
    # The reverse alone (no forward rounding): distance of F(ecef2llh(p)) from the double p.
    la, lo, hh = results['vessel_kinematics.ecef2llh']
    rev = np.array([distance(mp_llh2ecef(*v), q)
                    for v, q in zip(zip(la.tolist(), lo.tolist(), hh.tolist()), p_mp)])
    print(f'   ecef2llh alone, |F(ecef2llh(p)) - p| / max(1, r/a): max '
          f'{np.max(rev / scale) * 1e9:.3g} nm')
    by_height = {float(hv): np.max((rev / scale)[h == hv]) * 1e9 for hv in heights}
    print('   by height (m: nm): ' + ', '.join(f'{k:.0e}: {v:.2g}' for k, v in by_height.items()))


def lat_deg_of(lat: float) -> str:
    """Format a latitude (rad) in degrees."""
    return f'{math.degrees(lat):.6g}'


def best_times(funcs, repeat: int = 7) -> list[float]:
    """Return the best wall time (s) of each function, calls interleaved (fair under load)."""
    best = [math.inf] * len(funcs)
    for _ in range(repeat):
        for i, func in enumerate(funcs):
            start = time.perf_counter()
            func()
            best[i] = min(best[i], time.perf_counter() - start)
    return best


def throughput(n: int = 1_000_000) -> None:
    """Print vectorised times on n points, ours vs pyproj, in the same run."""
    rng = np.random.default_rng(0)
    lat = rng.uniform(-math.pi / 2, math.pi / 2, n)
    lon = rng.uniform(-math.pi, math.pi, n)
    h = rng.uniform(-1e3, 1e4, n)
    lat_deg, lon_deg = np.degrees(lat), np.degrees(lon)
    p = geo.llh2ecef(lat, lon, h)
    x, y, z = (np.ascontiguousarray(p[:, i]) for i in range(3))
    forward = pyproj.Transformer.from_crs('EPSG:4979', 'EPSG:4978', always_xy=True)
    inverse = pyproj.Transformer.from_crs('EPSG:4978', 'EPSG:4979', always_xy=True)
    rows = [
        ('llh2ecef', lambda: geo.llh2ecef(lat, lon, h),
         lambda: forward.transform(lon_deg, lat_deg, h)),
        ('ecef2llh', lambda: geo.ecef2llh(p), lambda: inverse.transform(x, y, z)),
    ]
    print(f'\n2. vectorised throughput on {n:.0e} points (best of 7, interleaved; ours takes '
          f'radians and a (n, 3) array, pyproj degrees and x, y, z arrays)')
    for name, ours, theirs in rows:
        t_ours, t_proj = best_times([ours, theirs])
        print(f'   {name:9s} ours {t_ours * 1e3:7.1f} ms   pyproj {t_proj * 1e3:7.1f} ms   '
              f'pyproj/ours = {t_proj / t_ours:.2f}x  ({n / t_ours / 1e6:.1f} M points/s)')


def per_call(stmt, number: int = 20000) -> float:
    """Return the best time per call (us) of ``stmt`` over 7 repeats."""
    return min(timeit.repeat(stmt, number=number, repeat=7)) / number * 1e6


def per_call_pair(ours, theirs, number: int = 20000) -> tuple[float, float]:
    """Return the best time per call (us) of two callables, measured interleaved."""
    best = [math.inf, math.inf]
    for _ in range(7):
        for i, func in enumerate((ours, theirs)):
            best[i] = min(best[i], timeit.timeit(func, number=number) / number * 1e6)
    return best[0], best[1]


def scalar_calls() -> None:
    """Print single-point call times, ours (math path) vs pyproj and pymap3d."""
    lat, lon, h = 0.8, 0.2, 35.0
    lat_deg, lon_deg = math.degrees(lat), math.degrees(lon)
    x, y, z = geo.llh2ecef(lat, lon, h)
    forward = pyproj.Transformer.from_crs('EPSG:4979', 'EPSG:4978', always_xy=True)
    inverse = pyproj.Transformer.from_crs('EPSG:4978', 'EPSG:4979', always_xy=True)
    t_fwd, t_proj_fwd = per_call_pair(lambda: geo.llh2ecef(lat, lon, h),
                                      lambda: forward.transform(lon_deg, lat_deg, h))
    t_inv, t_proj_inv = per_call_pair(lambda: geo.ecef2llh((x, y, z)),
                                      lambda: inverse.transform(x, y, z))
    one = np.array([lat])
    ned1 = np.array([[10.0, 20.0, 1.0]])
    rows = [
        ('llh2ecef(lat, lon, h)', t_fwd, t_proj_fwd),
        ('ecef2llh((x, y, z))', t_inv, t_proj_inv),
        ('llh2ned(6 floats)', per_call(lambda: geo.llh2ned(lat, lon, h, 0.8001, 0.2, 0.0)),
         None),
        ('  numpy body, batch of 1',
         per_call(lambda: geo.llh2ned(one, lon, h, 0.8001, 0.2, 0.0)), None),
        ('ned2llh((n, e, d), origin)',
         per_call(lambda: geo.ned2llh((10.0, 20.0, 1.0), 0.8, 0.2, 0.0)), None),
        ('  numpy body, batch of 1', per_call(lambda: geo.ned2llh(ned1, 0.8, 0.2, 0.0)), None),
        ('llh2flat(6 floats)', per_call(lambda: geo.llh2flat(lat, lon, h, 0.8001, 0.2, 0.0)),
         None),
        ('  numpy body, batch of 1',
         per_call(lambda: geo.llh2flat(one, lon, h, 0.8001, 0.2, 0.0)), None),
        ('flat2llh((n, e, d), origin)',
         per_call(lambda: geo.flat2llh((10.0, 20.0, 1.0), 0.8, 0.2, 0.0)), None),
        ('  numpy body, batch of 1', per_call(lambda: geo.flat2llh(ned1, 0.8, 0.2, 0.0)),
         None),
    ]
    t_map = per_call(lambda: pymap3d.ecef2geodetic(x, y, z, deg=False), number=2000)
    print('\n3. single-point calls (best of 7, interleaved with pyproj; us per call, incl. a '
          'lambda call)')
    print(f'   pyproj Transformer.transform: forward {t_proj_fwd:.2f} us, inverse '
          f'{t_proj_inv:.2f} us; pymap3d.ecef2geodetic {t_map:.2f} us')
    for name, t_ours, t_ref in rows:
        ratio = f'   pyproj/ours = {t_ref / t_ours:.2f}x' if t_ref else ''
        print(f'   {name:28s} {t_ours:6.2f} us{ratio}')


def main() -> None:
    """Run the three benchmarks (only the third with ``--scalar``)."""
    if sys.argv[1:] != ['--scalar']:
        accuracy()
        throughput()
    scalar_calls()


if __name__ == '__main__':
    main()
