"""
The ``replay`` command: ``replay INPUT [INPUT ...] OUTPUT [--params-file FILE] [-p NAME:=VALUE]``.

One input bag: its replay (:func:`~.run.run`) and a summary; several inputs, or a directory of
bags: one output each under OUTPUT and a table (:func:`~.many.run_many`, ``--jobs`` bags at a
time, by default as many as there are cores). Parameters come from a ROS 2 parameters file and
``-p`` values, read as the node reads them (:mod:`vessel_kinematics.ros.params_file`: the same
limits and the same one-line refusals). Exit status: 0 done, 1 the run failed (no output
written: among others a run with no navigation output at all, or whose every input was refused),
2 the command line or the parameters are unusable, 3 written but suspect (more than half of an
input's messages refused: the output is there, the summary printed, and one line on stderr says
which), 130 interrupted (SIGINT), 143 terminated (SIGTERM), 129
hung up (SIGHUP): 128 + the signal, as a shell reports a process the signal killed, but after
a clean stop (the staging directory removed, no output written, the previous one kept; or,
stopped once the output was in place, while scoring or plotting, the output complete and the
line saying so; with several inputs, the outputs of the bags done before the stop kept,
no table); a plot that cannot be written once the output is, is a warning, not an error;
every error is one line on stderr. A closed stdout or stderr (a consumer gone) is not an
error of its own.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import os
from pathlib import Path
import signal
import sys
from typing import Any, Mapping, Sequence

from vessel_kinematics.ros.params import NavigatorParams, ParameterError, PARAMETERS
from vessel_kinematics.ros.params_file import (parse_value, read_params_file, unknown_names_line,
                                               without_removed)
from vessel_kinematics.tools.replay.errors import error_line, EXPECTED, ReplayError
from vessel_kinematics.tools.replay.many import default_jobs, is_many, rows_table, run_many
from vessel_kinematics.tools.replay.run import run

__all__ = ['build_parser', 'load_params', 'main', 'parse_param', 'STOP_SIGNALS', 'Stopped',
           'SUSPECT', 'USAGE_ERROR']

#: The exit status of an unusable command line or parameter (as argparse's).
USAGE_ERROR = 2
#: The exit status of a run whose output is written but suspect (most of an input refused).
SUSPECT = 3
#: The signals that stop a replay cleanly, as Ctrl-C does (systemd and docker send SIGTERM).
STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)


class Stopped(KeyboardInterrupt):
    """A stop signal, raised where the replay is so that it unwinds as on Ctrl-C."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _stop(signum: int, _frame: Any) -> None:
    for other in (signal.SIGINT, *STOP_SIGNALS):   # the clean-up is not interrupted again
        signal.signal(other, signal.SIG_IGN)
    raise Stopped(signum)


@contextlib.contextmanager
def _stop_signals() -> Any:
    """Turn SIGTERM and SIGHUP into :class:`Stopped` while the replay runs (main thread)."""
    try:
        previous = {s: signal.getsignal(s) for s in (signal.SIGINT, *STOP_SIGNALS)}
        for s in STOP_SIGNALS:
            signal.signal(s, _stop)
    except ValueError:                     # not the main thread: leave the handlers alone
        yield
        return
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler if handler is not None else signal.SIG_DFL)


def _say(line: str, stream: Any) -> None:
    """Print a line; a stream whose reader is gone (a closed pipe, a hung-up tty) is ignored."""
    try:
        print(line, file=stream, flush=True)
    except (BrokenPipeError, OSError):
        with contextlib.suppress(OSError, ValueError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), stream.fileno())


def _warn(line: str) -> None:
    print(f'replay: warning: {line}', file=sys.stderr)


def parse_param(text: str) -> tuple[str, Any]:
    """Parse ``NAME:=VALUE`` (the value read as rcl reads ``-p``: YAML, ``2e0`` a float)."""
    name, sep, value = text.partition(':=')
    if not sep or not name:
        raise ParameterError(text[:40], 'is not NAME:=VALUE (e.g. -p gnss.enabled:=false)')
    return name, parse_value(value, name)


def load_params(params_file: str | Path | None = None,
                overrides: Mapping[str, Any] | None = None,
                node_fqn: str = '/navigator') -> NavigatorParams:
    """
    Return validated parameters from a ROS 2 parameters file and ``name: value`` overrides.

    The file is read as the node reads it (:func:`~vessel_kinematics.ros.params_file.
    read_params_file`: rcl's wildcard keys for ``node_fqn``); names that are not the
    navigator's are ignored with one warning, as the node does. Raises
    :class:`~vessel_kinematics.ros.params.ParameterError` with one line.
    """
    values: dict[str, Any] = {}
    if params_file is not None:
        read = read_params_file(params_file, node_fqn)
        if not read.sections:
            _warn(f'{params_file} sets no parameter of {node_fqn} (keys: /**, /**/navigator, '
                  '/ns/navigator or navigator)')
        if read.unknown:
            _warn(unknown_names_line(read.unknown, str(params_file)))
        for line in read.ignored:
            _warn(line)
        values.update(read.values)
    if overrides:
        kept, ignored = without_removed(overrides, '-p')
        for line in ignored:
            _warn(line)
        values.update(kept)
    return NavigatorParams.from_flat(values)


def build_parser() -> argparse.ArgumentParser:
    """Return the command line parser of ``replay``."""
    names = ', '.join(p.name for p in PARAMETERS)
    parser = argparse.ArgumentParser(
        prog='replay',
        description='Replay a recorded bag (rosbag2 mcap/sqlite3 or ROS 1) or a marine log '
                    '(NMEA 0183, an NMEA 2000 capture) through the '
                    "vessel_kinematics navigator's estimator and write its outputs, TF and the "
                    'copied inputs to a rosbag2 mcap bag.',
        epilog='example: replay run.bag out --params-file config/navigator.yaml '
               '--remap fix:=/gps/fix imu:=/imu/data velocity:=/wheel/odom --plot run.png; '
               'replay my_log.nmea out; replay archive/ out_dir --jobs 2. '
               f'Parameters: {names}.')
    parser.add_argument('paths', nargs='+', metavar='INPUT [INPUT ...] OUTPUT',
                        help='input bags: rosbag2 directories (mcap, sqlite3), ROS 1 .bag or '
                             '.mcap files, or directories of them; then the output rosbag2 '
                             'directory (mcap), which must not exist. With several inputs (or '
                             'a directory of bags) OUTPUT is a directory holding one output '
                             'per input, OUTPUT/<input name>, and a table is printed')
    parser.add_argument('--params-file', metavar='FILE',
                        help='ROS 2 parameters file (navigator: ros__parameters: or /**)')
    parser.add_argument('-p', '--param', action='append', default=[], metavar='NAME:=VALUE',
                        help='set one parameter over the file, e.g. -p gnss.enabled:=false')
    parser.add_argument('-r', '--remap', nargs='+', action='extend', default=[],
                        metavar='NAME:=TOPIC',
                        help='read input NAME (fix, imu, velocity, gnss_velocity) from bag '
                             'topic TOPIC; defaults fix:=/fix imu:=/imu velocity:=/velocity '
                             '(a marine log: velocity:=/speed_log)')
    parser.add_argument('--plot', metavar='FILE.png', help='write a figure of the run')
    parser.add_argument('--no-copy-inputs', action='store_true',
                        help="do not copy the input bag's topics into the output")
    parser.add_argument('--overwrite', action='store_true',
                        help='replace OUTPUT if it is an existing rosbag2 bag')
    parser.add_argument('--no-progress', action='store_true', help='no progress bar')
    parser.add_argument('--by-stamp', action='store_true',
                        help='hand the messages on by header stamp (merged through a 10 s '
                             "reorder buffer) instead of the bag's log-time order, the "
                             'arrival the node saw: for a bag whose log times say nothing '
                             'of the arrival'),
    parser.add_argument('--date', type=_date, metavar='YYYY-MM-DD',
                        help='the UTC date of a marine log whose only times are times of day '
                             '(NMEA 0183 GGA or GLL without RMC or ZDA, an NMEA 2000 capture '
                             'of times of day without GNSS time); a log with its own date '
                             'keeps it')
    parser.add_argument('-j', '--jobs', type=int, default=None, metavar='N',
                        help='with several inputs, replay N bags at a time in separate '
                             'processes (default: one per core)')
    return parser


def _identity(path: str) -> tuple[int, int] | None:
    """Return a path's (device, inode), None when missing: a new output is another inode."""
    try:
        status = os.stat(path)
    except (OSError, ValueError):
        return None
    return status.st_dev, status.st_ino


def _date(text: str) -> datetime.date:
    try:
        return datetime.date.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a date (YYYY-MM-DD)') from None


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``replay`` command; return the exit status (see the module's notes)."""
    with _stop_signals():
        return _main(argv)


def _main(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    *inputs, output = args.paths
    if not inputs:
        parser.error('the following arguments are required: output')
    before = _identity(output)       # a stop signal: is the output written since?
    many = False
    try:
        try:
            overrides = dict(parse_param(p) for p in args.param)
            params = load_params(args.params_file, overrides)
        except ParameterError as error:
            _say(f'replay: error: {error_line(error)}', sys.stderr)
            return USAGE_ERROR
        if args.jobs is not None and args.jobs < 1:
            raise ReplayError(f'--jobs {args.jobs}: must be at least 1')
        many = is_many(inputs)
        if many:
            if args.plot is not None:
                raise ReplayError('--plot takes one input bag (several inputs print a table)')
            rows = run_many(inputs, output, params, args.remap,
                            jobs=default_jobs() if args.jobs is None else args.jobs,
                            copy_inputs=not args.no_copy_inputs, overwrite=args.overwrite,
                            by_stamp=args.by_stamp, date=args.date)
            _say(rows_table(rows), sys.stdout)
            return 0 if all(row.ok for row in rows) else 1
        summary = run(inputs[0], output, params, args.remap,
                      copy_inputs=not args.no_copy_inputs, plot=args.plot,
                      progress=False if args.no_progress else None,
                      overwrite=args.overwrite, by_stamp=args.by_stamp, date=args.date)
    except KeyboardInterrupt as stop:
        signum = stop.signum if isinstance(stop, Stopped) else signal.SIGINT
        what = {signal.SIGTERM: 'terminated (SIGTERM)', signal.SIGHUP: 'hung up (SIGHUP)'}.get(
            signal.Signals(signum), 'interrupted')
        if not many and _identity(output) not in (None, before):
            _say(f'replay: error: {what} after the output was written: {output} is complete '
                 '(no summary, no plot)', sys.stderr)
        elif many:
            _say(f'replay: error: {what}; the outputs of the bags done before it are in '
                 f'{output}, none written for the others (no table)', sys.stderr)
        else:
            _say(f'replay: error: {what}; no output written', sys.stderr)
        return 128 + signum
    except Exception as error:  # noqa: B902 - the promise: one line, never a traceback
        if os.environ.get('VK_REPLAY_TRACEBACK') and not isinstance(error, EXPECTED):
            raise
        line = error_line(error)
        if not isinstance(error, EXPECTED):
            line += ' (VK_REPLAY_TRACEBACK=1 shows the traceback)'
        _say(f'replay: error: {line}', sys.stderr)
        return 1
    _say(summary.text(), sys.stdout)
    if summary.problems:
        _say(f'replay: error: output written but suspect: {"; ".join(summary.problems)}',
             sys.stderr)
        return SUSPECT
    return 0
