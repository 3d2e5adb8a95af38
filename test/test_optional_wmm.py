"""
``imu.declination: auto`` without NOAA's model installed: one line, never a traceback per fix.

The World Magnetic Model (package wmm-calculator) is optional. A replay run in a Python that
cannot import ``wmm`` (``sys.modules['wmm'] = None``: import and ``find_spec`` answer as for an
absent package) says so in one note, applies no declination, and its estimates say why.
"""

from __future__ import annotations

from pathlib import Path
import subprocess
import sys

from test_replay import write_voyage

#: Python's own way to make a package unimportable, then the replay's command.
WITHOUT_WMM = ("import sys; sys.modules['wmm'] = None; "
               'from vessel_kinematics.tools.replay import main; sys.exit(main(sys.argv[1:]))')


def test_a_missing_world_magnetic_model_is_one_line(tmp_path: Path) -> None:
    bag = write_voyage(tmp_path / 'in', duration=3.0)
    done = subprocess.run([sys.executable, '-c', WITHOUT_WMM, str(bag), str(tmp_path / 'out'),
                           '-p', 'imu.declination:=auto', '--no-progress', '--no-copy-inputs'],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert 'Traceback' not in done.stderr + done.stdout
    said = [line.split()[0] for line in done.stdout.splitlines() if 'wmm-calculator' in line]
    # One note at the start, and the estimates' reason: no line per fix.
    assert sorted(said) == ['estimated', 'note'], done.stdout
    assert 'declination (deg) not applied: imu.declination auto needs' in done.stdout
