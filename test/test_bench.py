"""
The quick benchmarks run to the end on a short input (their numbers are not checked).

A benchmark nobody runs rots: ``bench_pipeline.py`` handed every message an arrival from
``perf_counter_ns`` while its stamps were in 2023, so the pipeline refused the first IMU as a
future stamp and the bench stopped with a traceback. Each bench here runs as ``make bench``
runs it, on a few seconds of input, and must print its result line. The DDS benches
(``bench_navigator.py``, ``soak_navigator.py``) and the long ones (geodesy, quaternion) are
left to ``make bench``.
"""

from __future__ import annotations

from pathlib import Path
import subprocess
import sys

import pytest

BENCH = Path(__file__).resolve().parents[1] / 'bench'


@pytest.mark.parametrize('args, expected', [
    (['bench_pipeline.py', '--seconds', '1.5', '--repeat', '1'], '(b) the default publish_rate'),
    (['bench_pipeline.py', '--seconds', '1.5', '--repeat', '1', '--fix-delay', '0.3'],
     'fixes 0.3 s late'),
    (['bench_estimator.py', '--seconds', '2', '--repeat', '1'], 'peer: rosbags'),
    (['bench_replay.py', '--messages', '3000', '--repeat', '1'], 'replay / rosbags'),
])
def test_bench_runs_to_its_result(args: list[str], expected: str) -> None:
    """Each quick bench exits 0 and prints its result line."""
    run = subprocess.run([sys.executable, str(BENCH / args[0]), *args[1:]],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    assert expected in run.stdout, run.stdout[-2000:]
